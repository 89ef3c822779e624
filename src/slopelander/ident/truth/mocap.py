"""A motion-capture system observing the truth: what a lab's export of a drop would hold.

Unlike :mod:`slopelander.ident.synth` (white noise added to the body's pose on a grid that has
a sample exactly at contact), this models the measurement the way it is made: markers on the
body, each seen with its own jitter, the pose solved from them by a least-squares rigid fit;
frames at the camera's rate with a random phase against the instant of contact; a latency;
frames the tracker lost (absent from the export: the time column jumps); rates differentiated
from the noisy poses by a least-squares slope over a window of frames, using their real times,
centred on every exported frame (the take runs on a few frames beyond the export).
The recording declares its noise (``meta.noise``) as docs/recordings.md and docs/ident.md say:
the pose noise the marker jitter makes, the latency, and here also the share of lost frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from slopelander.ident.recording import Drop
from slopelander.ident.synth import centred_rates, extend
from slopelander.model import LandingConditions, Outcome

MARKERS = ((-0.12, 0.02), (0.12, 0.02), (0.0, 0.07), (0.05, -0.04))
"""m, body frame (x forward, z up, about the centre of mass): four markers on the frame."""


@dataclass(frozen=True)
class MotionCapture:
    """A lab's camera system (defaults: 200 Hz, 1 mm per marker, 2 ms latency, 1 % lost)."""

    sample_rate: float = 200.0
    latency: float = 0.002
    """s: a frame shows the body this long before its time stamp."""
    marker_sd: float = 1.0e-3
    """m: jitter of each marker's position, per axis, independent between markers and frames."""
    dropped: float = 0.01
    """Share of frames lost (the tracker lost the body); they are missing from the export."""
    rate_window: int = 7
    """Frames of the least-squares slope the export's rates come from."""
    markers: tuple[tuple[float, float], ...] = MARKERS

    def __post_init__(self) -> None:
        if not 10.0 <= self.sample_rate <= 2400.0:
            raise ValueError("motion capture sample_rate must lie within 10..2400 Hz")
        for name in ("latency", "marker_sd"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"motion capture {name} must be a finite number >= 0")
        if not 0.0 <= self.dropped < 0.5:
            raise ValueError("motion capture dropped must be a share within 0..0.5")
        if self.rate_window < 3 or self.rate_window % 2 == 0:
            raise ValueError("motion capture rate_window must be an odd number of frames >= 3")
        if len(self.markers) < 2:
            raise ValueError("motion capture needs at least two markers to see an angle")

    def pose_sd(self) -> tuple[float, float]:
        """(position sd in m, angle sd in deg) of the pose the rigid fit solves from the markers:
        the centroid averages the markers' jitter, the angle is set by their spread about it."""
        r = np.asarray(self.markers, dtype=float)
        spread = float(((r - r.mean(axis=0)) ** 2).sum())
        return self.marker_sd / math.sqrt(len(r)), math.degrees(self.marker_sd / math.sqrt(spread))


def _fit_pose(seen: np.ndarray, body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rigid fit (2-D Kabsch) of body-frame markers to seen world markers, per
    frame: centroid offset and angle. ``seen`` is (frames, markers, 2)."""
    bc = body - body.mean(axis=0)
    sc = seen - seen.mean(axis=1, keepdims=True)
    # angle maximising sum_i (R b_i) . s_i:  atan2(sum b x s, sum b . s)
    cross = (bc[None, :, 0] * sc[:, :, 1] - bc[None, :, 1] * sc[:, :, 0]).sum(axis=1)
    dot = (bc[None, :, 0] * sc[:, :, 0] + bc[None, :, 1] * sc[:, :, 1]).sum(axis=1)
    angle = np.arctan2(cross, dot)
    c, s = np.cos(angle), np.sin(angle)
    mb = body.mean(axis=0)
    rot_mb = np.column_stack([c * mb[0] - s * mb[1], s * mb[0] + c * mb[1]])
    centre = seen.mean(axis=1) - rot_mb
    return centre, angle


def observe(
    truth: Callable[[np.ndarray], np.ndarray],
    mocap: MotionCapture,
    rng: np.random.Generator,
    *,
    before: float = 0.05,
    duration: float = 0.6,
) -> tuple[np.ndarray, np.ndarray]:
    """Frame times and the six recorded states of one drop. ``truth(times)`` gives the true
    (x, z, pitch, ...) at any times (s from first contact)."""
    dt = 1.0 / mocap.sample_rate
    phase = round(rng.uniform(0.0, dt), 6)  # the cameras do not know when the feet touch (1 us: the export)
    t = np.arange(math.ceil((-before - phase) / dt), math.floor((duration - phase) / dt) + 1) * dt + phase
    # the take runs on beyond the export: its first and last rates are centred on frames there
    h = mocap.rate_window // 2
    te = extend(t, h)
    pose = truth(te - mocap.latency)
    body = np.asarray(mocap.markers, dtype=float)
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    world = np.stack(
        [
            pose[:, None, 0] + c[:, None] * body[None, :, 0] - s[:, None] * body[None, :, 1],
            pose[:, None, 1] + s[:, None] * body[None, :, 0] + c[:, None] * body[None, :, 1],
        ],
        axis=2,
    )
    inside = slice(h, len(te) - h)
    world[inside] += rng.normal(0.0, mocap.marker_sd, world[inside].shape)
    beyond = rng.spawn(1)[0]  # the frames beyond the export: a generator of their own
    out = np.r_[0:h, len(te) - h : len(te)]
    world[out] += beyond.normal(0.0, mocap.marker_sd, world[out].shape)
    centre, angle = _fit_pose(world, body)
    pos = np.column_stack([centre, angle])
    keep = np.ones(len(te), dtype=bool)
    keep[inside] = rng.uniform(size=len(t)) >= mocap.dropped
    keep[[h, len(te) - h - 1]] = True  # the export spans the take
    te, pos = te[keep], pos[keep]
    rates = centred_rates(pos, te, mocap.rate_window)
    return te[h : len(te) - h], np.column_stack([pos[h : len(te) - h], rates])


def record(
    name: str,
    cond: LandingConditions,
    truth: Callable[[np.ndarray], np.ndarray],
    outcome: Outcome | None,
    mocap: MotionCapture,
    rng: np.random.Generator,
    *,
    duration: float = 0.6,
    source: str = "independent truth (solve_ivp), motion-capture model",
    seed: int | None = None,
) -> Drop:
    """One drop as the lab's export of it would read, with its noise declared in ``meta``."""
    t, states = observe(truth, mocap, rng, duration=duration)
    pos_sd, ang_sd = mocap.pose_sd()
    meta = {
        "rates": {"method": "lsq_slope", "window": mocap.rate_window},
        "noise": {
            "position_sd_m": pos_sd,
            "angle_sd_deg": ang_sd,
            "latency_s": mocap.latency,
            "marker_sd_m": mocap.marker_sd,
            "markers": len(mocap.markers),
            "sample_rate_hz": mocap.sample_rate,
            "dropped_frames": mocap.dropped,
            **({"seed": seed} if seed is not None else {}),
        },
    }
    return Drop(name, t, states, cond, outcome, source, meta)
