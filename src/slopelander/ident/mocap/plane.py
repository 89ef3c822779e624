"""The roof and the landing frame: the slope's plane, its fall line, and the model's axes.

The model's frame (docs/recordings.md): x horizontal and positive downhill, z up, pitch
counter-clockwise with x to the right; the surface passes through the origin. Here it is
built from the roof plane's normal n (pointing up) and the vertical u: the fall line's
horizontal direction is n's horizontal part (a normal leans downhill), y = z x x completes
the frame and is the direction out of the landing plane.
"""

from __future__ import annotations

import math

import numpy as np

FLAT_DEG = 0.5
"""deg: below this the roof is taken as flat and x follows the body's own forward axis."""


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Centroid, unit normal and RMS distance of points (k, 3) from their least-squares plane."""
    c = points.mean(axis=0)
    _, sv, vt = np.linalg.svd(points - c)
    n = vt[2]
    return c, n / np.linalg.norm(n), float(sv[2] / math.sqrt(len(points)))


def axis_vector(axis: str) -> np.ndarray:
    """``+Z`` -> (0, 0, 1) and so on."""
    v = np.zeros(3)
    v["XYZ".index(axis[1])] = 1.0 if axis[0] == "+" else -1.0
    return v


def landing_frame(normal: np.ndarray, up: np.ndarray, forward: np.ndarray) -> tuple[np.ndarray, float]:
    """Rows (x downhill, y out of the plane, z up) in capture axes, and the slope in degrees.
    ``forward`` (the body's forward axis) sets x on a flat roof."""
    n = normal if normal @ up > 0 else -normal
    slope = math.degrees(math.acos(min(1.0, float(n @ up))))
    horiz = n - (n @ up) * up
    if slope < FLAT_DEG:
        horiz = forward - (forward @ up) * up
    ex = horiz / np.linalg.norm(horiz)
    ey = np.cross(up, ex)
    return np.vstack([ex, ey, up]), slope
