"""Landing phases of a recorded drop, found from the measured states alone.

Errors are reported per phase so that a missing effect shows where it acts: a wrong contact
law in the first contact, a wrong joint friction in the compression, a wrong foot friction in
the settling. The phases come from the measurement (not the model) so every model under test
is judged on the same windows.
"""

from __future__ import annotations

import numpy as np

PHASES: tuple[str, ...] = ("flight", "first contact", "compression", "rebound", "settling", "sliding")
FIRST_CONTACT = 0.02
"""s after first contact counted as the impact transient."""
SLIDE_SPEED = 0.1
"""m/s along the slope above which a body moving more along the slope than across it slides."""


def _smooth(v: np.ndarray, n: int) -> np.ndarray:
    if n <= 1 or len(v) < n:
        return v
    return np.convolve(v, np.ones(n) / n, mode="same")


def phase_labels(
    t: np.ndarray, z_rate: np.ndarray, x_rate: np.ndarray | None = None, slope_deg: float = 0.0
) -> np.ndarray:
    """Index into :data:`PHASES` for every sample.

    flight: before first contact (t < 0); first contact: the first 20 ms; compression: until the
    (smoothed) vertical speed first turns upward; rebound: while it stays upward; settling: after.
    With ``x_rate`` and the slope: sliding, where a compression or settling sample moves along
    the slope faster than :data:`SLIDE_SPEED` and faster along it than across it (a sliding
    drop's vertical speed never turns upward, so it read "compression" to the end).
    """
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.005
    vz = _smooth(z_rate, max(1, round(0.015 / dt)))
    labels = np.full(len(t), 4, dtype=np.int64)
    labels[t < 0] = 0
    contact = t >= 0
    labels[contact & (t < FIRST_CONTACT)] = 1
    later = np.flatnonzero(t >= FIRST_CONTACT)
    if later.size == 0:
        return labels
    up = later[vz[later] > 0]
    end_comp = int(up[0]) if up.size else len(t)
    labels[later[0] : end_comp] = 2
    if end_comp < len(t):
        down = np.flatnonzero((np.arange(len(t)) > end_comp) & (vz <= 0))
        end_reb = int(down[0]) if down.size else len(t)
        labels[end_comp:end_reb] = 3
    if x_rate is not None:
        a = np.radians(slope_deg)
        vx = _smooth(x_rate, max(1, round(0.015 / dt)))
        along = np.cos(a) * vx - np.sin(a) * vz
        into = np.sin(a) * vx + np.cos(a) * vz
        slide = (np.abs(along) > SLIDE_SPEED) & (np.abs(into) < np.abs(along))
        labels[slide & (t >= FIRST_CONTACT) & ((labels == 2) | (labels == 4))] = 5
    return labels


def phase_spans(t: np.ndarray, labels: np.ndarray) -> list[tuple[int, float, float]]:
    """(phase index, start, end) of each run of one phase, for shading plots."""
    spans = []
    start = 0
    for i in range(1, len(labels) + 1):
        if i == len(labels) or labels[i] != labels[start]:
            spans.append((int(labels[start]), float(t[start]), float(t[min(i, len(t) - 1)])))
            start = i
    return spans
