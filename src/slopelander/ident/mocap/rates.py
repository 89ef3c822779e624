"""Rates of imported takes: a Savitzky-Golay derivative, the same for the data and the model.

The filter is centred (no lag) and fitted over a fixed number of frames. Its derivative follows
the true one up to a bandwidth; above it, the impact's sharp change of speed is smoothed. The
recording says which filter it used (``meta.rates``: window, polyorder, frame spacing, lag and
-3 dB bandwidth), and ``compare`` differentiates the model's positions with the same filter, so
the smoothing is not mistaken for missing physics. A window that touches a gap (NaN) gives NaN:
a rate is never made across a frame that was not seen, nor at the first and last frames.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view


def coefficients(window: int, polyorder: int, dt: float) -> np.ndarray:
    """Weights whose dot product with ``window`` frames is the derivative at the middle one."""
    from scipy.signal import savgol_coeffs

    return np.asarray(savgol_coeffs(window, polyorder, deriv=1, delta=dt, use="dot"))


def savgol_rates(pos: np.ndarray, dt: float, window: int, polyorder: int) -> np.ndarray:
    """Derivative of each column of ``pos`` (frames on a uniform grid of ``dt`` s); NaN where the
    centred window does not fit inside the take or holds a gap."""
    pos = np.asarray(pos, dtype=float)
    out = np.full(pos.shape, np.nan)
    h = window // 2
    if len(pos) < window:
        return out
    win = sliding_window_view(pos, window, axis=0)  # (n - window + 1, columns, window)
    out[h : len(pos) - h] = win @ coefficients(window, polyorder, dt)
    return out


def bandwidth(window: int, polyorder: int, dt: float) -> float:
    """Hz: the frequency up to which the filter's derivative stays within -3 dB of the true one."""
    c = coefficients(window, polyorder, dt)
    k = np.arange(len(c)) - len(c) // 2
    f = np.linspace(0.01, 0.5 / dt, 4000)
    # c is odd about the middle: the response is imaginary; compare it with i 2 pi f
    gain = np.abs(np.sum(c[None, :] * np.exp(-2j * math.pi * f[:, None] * k[None, :] * dt), axis=1))
    ratio = gain / (2 * math.pi * f)
    below = np.flatnonzero(ratio < 1 / math.sqrt(2))
    return float(f[below[0]]) if below.size else float(f[-1])


def window_frames(window_s: float, rate: float, polyorder: int) -> int:
    """The odd number of frames nearest ``window_s`` at ``rate``, at least ``polyorder + 2``."""
    n = round(window_s * rate)
    n = n + 1 if n % 2 == 0 else n
    least = polyorder + 2 if (polyorder + 2) % 2 else polyorder + 3
    return max(n, least, 3)


def describe(window: int, polyorder: int, dt: float) -> dict:
    """The ``meta.rates`` entry of a recording whose rates this filter made."""
    return {
        "method": "savgol",
        "window": int(window),
        "polyorder": int(polyorder),
        "dt": float(dt),
        "lag_s": 0.0,
        "bandwidth_hz": round(bandwidth(window, polyorder, dt), 2),
    }
