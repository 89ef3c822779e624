"""The body's pose from its marker cluster: a least-squares rigid fit per frame.

The fit is Kabsch's (the SVD solution of Wahba's problem, what
``scipy.spatial.transform.Rotation.align_vectors`` solves for one frame), done for all frames
that see the same markers at once: a 1-minute take at 200 Hz is 12 000 fits. A frame that sees
fewer than three markers, or only markers in a line, has no pose (NaN): it stays a gap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slopelander.ident.mocap.take import MocapError


@dataclass(frozen=True)
class ClusterFit:
    rotation: np.ndarray
    """(frames, 3, 3) body-to-capture rotation; NaN where the frame has no pose."""
    position: np.ndarray
    """(frames, 3) m, the body frame's origin (the centre of mass) in the capture's axes."""
    residual: np.ndarray
    """(frames, markers) m, each marker's distance from where the fitted body puts it."""
    seen: np.ndarray
    """(frames,) markers used per frame."""
    marker_sd: float
    """m: jitter of one marker per axis, from the fit residuals (3 m - 6 degrees of freedom)."""


def fit_cluster(xyz: np.ndarray, body: np.ndarray) -> ClusterFit:
    """Fit ``body`` (markers, 3; body frame) to the seen markers ``xyz`` (frames, markers, 3)."""
    n, m, _ = xyz.shape
    vis = np.isfinite(xyz).all(axis=2)
    rot = np.full((n, 3, 3), np.nan)
    pos = np.full((n, 3), np.nan)
    res = np.full((n, m), np.nan)
    patterns, inverse = np.unique(vis, axis=0, return_inverse=True)
    for k, mask in enumerate(patterns):
        if mask.sum() < 3:
            continue
        frames = np.flatnonzero(inverse.ravel() == k)
        b = body[mask]
        bm = b.mean(axis=0)
        bc = b - bm
        s = xyz[frames][:, mask]
        sm = s.mean(axis=1)
        sc = s - sm[:, None, :]
        h = np.einsum("mi,fmj->fij", bc, sc)
        u, sv, vt = np.linalg.svd(h)
        if sv[0, 1] < 1e-6 * max(sv[0, 0], 1e-12):
            continue  # the markers seen lie on a line: no rotation about it
        d = np.sign(np.linalg.det(np.einsum("fji,fkj->fik", vt, u)))
        fix = np.ones((len(frames), 3))
        fix[:, 2] = d
        r = np.einsum("fji,fj,fkj->fik", vt, fix, u)  # V diag(1, 1, d) U^T
        rot[frames] = r
        pos[frames] = sm - np.einsum("fij,j->fi", r, bm)
        model = pos[frames][:, None, :] + np.einsum("fij,mj->fmi", r, body)
        res[frames] = np.linalg.norm(model - xyz[frames], axis=2)
    seen = vis.sum(axis=1)
    dof = np.where(np.isfinite(pos[:, 0]), 3 * seen - 6, 0)
    ssr = np.nansum(res**2, axis=1)
    sd = math.sqrt(float(ssr[dof > 0].sum()) / max(int(dof[dof > 0].sum()), 1))
    return ClusterFit(rot, pos, res, seen, sd)


def check_rigid(
    xyz: np.ndarray, body: np.ndarray, names: list[str], tol: float, where: tuple[str, str, str]
) -> None:
    """Refuse a cluster that is not the declared rigid shape: a pair of markers whose distance
    in the take differs from the markers file's by more than ``tol`` (median over frames), or
    that varies over the take by more than ``tol`` (a marker on a moving part)."""
    path, take, fieldname = where
    pairs = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            d = np.linalg.norm(xyz[:, i] - xyz[:, j], axis=1)
            d = d[np.isfinite(d)]
            if d.size >= 3:
                pairs.append((i, j, d))
    for i, j, d in pairs:  # first a shape that changes, then a shape that differs
        lo, hi = np.percentile(d, [2.5, 97.5])
        if hi - lo > 2 * tol:
            raise MocapError(
                path,
                take,
                fieldname,
                f"the cluster is not rigid: {names[i]}-{names[j]} varies by {1000 * (hi - lo):.1f} mm "
                f"over the take (95 % of frames; tolerance {1000 * 2 * tol:.1f} mm)",
            )
    for i, j, d in pairs:
        declared = float(np.linalg.norm(body[i] - body[j]))
        med = float(np.median(d))
        if abs(med - declared) > tol:
            raise MocapError(
                path,
                take,
                fieldname,
                f"markers {names[i]} and {names[j]} are {1000 * med:.1f} mm apart in the take, "
                f"{1000 * declared:.1f} mm in the markers file (tolerance {1000 * tol:.1f} mm): a "
                "marker is mislabelled or the body's coordinates are wrong",
            )
