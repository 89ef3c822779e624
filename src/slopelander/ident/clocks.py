"""Each drop's clock against the model's: a window per drop, and the lag within it that fits.

Why: t = 0 is the contact as the recording found it, and a few milliseconds matter: drops whose
frames lag it by 2 ms put a fitted k_g 4-6 % high in every one of 20 fits (the truth outside
every interval; benchmarks/interval_coverage.py). Each drop's clock is a nuisance fitted within
its window, as its initial state is taken from the recording."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from slopelander.ident.observe import observe, predict, trajectory
from slopelander.ident.recording import Drop
from slopelander.model import Model, Outcome

ALIGN_SIGMAS = 3.0
"""A drop's alignment window by default: this many of its recorded contact's standard deviations."""
ALIGN_MAX_S = 0.05


def align_windows(drops: Sequence[Drop], align_s: float | None = None, *, frame: bool = False) -> list[float]:
    """Each drop's alignment window (s): ``align_s`` for all, or by default
    :data:`ALIGN_SIGMAS` times the contact's standard deviation an imported take records
    (``meta.quality.contact_sd_s``), 0 where none is recorded (a simulator's drops) or, with
    ``frame``, one frame there (the median sample interval: a t = 0 found in the frames is the
    contact only to a frame)."""
    if align_s is not None:
        ok = isinstance(align_s, (int, float)) and not isinstance(align_s, bool)
        if not (ok and 0 <= align_s <= ALIGN_MAX_S):
            raise ValueError(f"the alignment window must be 0..{ALIGN_MAX_S:g} s, not {align_s!r}")
        return [float(align_s)] * len(drops)
    out = []
    for d in drops:
        quality = d.meta.get("quality") if isinstance(d.meta, dict) else None
        sd = quality.get("contact_sd_s") if isinstance(quality, dict) else None
        ok = isinstance(sd, (int, float)) and not isinstance(sd, bool) and math.isfinite(sd) and sd >= 0
        out.append(min(ALIGN_SIGMAS * float(sd) if ok else _frame(d) if frame else 0.0, ALIGN_MAX_S))
    return out


def _frame(drop: Drop) -> float:
    """The drop's median sample interval (s; 0 with fewer than two samples)."""
    t = np.asarray(drop.t, dtype=float)
    return float(np.median(np.diff(t))) if len(t) > 1 else 0.0


ALIGN_GRID = 5
"""Lags tried across a drop's window before parabolas refine the best of them."""
ALIGN_REFINE = 2


def best_lag(sse: Callable[[float], float], window: float) -> float:
    """The lag in [-window, window] where ``sse`` is least: a grid of :data:`ALIGN_GRID`, then
    :data:`ALIGN_REFINE` parabolas through the best point and its neighbours (the residual is
    close to linear in a lag of a few ms, its square a parabola); the best lag evaluated.
    Seven evaluations, not a search's fifteen or twenty: each costs a third of a simulation."""
    tried = {float(x): sse(float(x)) for x in np.linspace(-window, window, ALIGN_GRID)}
    for _ in range(ALIGN_REFINE):
        xs = sorted(tried)
        k = min(range(len(xs)), key=lambda i: tried[xs[i]])
        if k == 0 or k == len(xs) - 1:
            break  # at the window's edge: the edge it is
        (a, fa), (b, fb), (c, fc) = ((x, tried[x]) for x in xs[k - 1 : k + 2])
        den = (b - a) * (fb - fc) - (b - c) * (fb - fa)
        if den == 0:
            break
        x = b - 0.5 * ((b - a) ** 2 * (fb - fc) - (b - c) ** 2 * (fb - fa)) / den
        x = float(min(max(x, a), c))
        if x in tried:
            break
        tried[x] = sse(x)
    return min(tried, key=tried.__getitem__)


def aligned(
    model: Model, drop: Drop, window: float, scale: np.ndarray, *, outcome: bool = False
) -> tuple[np.ndarray, Outcome | None, float]:
    """:func:`predict` at the lag within +-``window`` whose residual after contact, ``scale``d
    per state, is least: the states, the outcome (with ``outcome``) and the lag."""
    if window <= 0:
        sim, out = predict(model, drop, outcome=outcome)
        return sim, out, 0.0
    tr = trajectory(model, drop, outcome=outcome, reach=window)
    after = drop.t >= 0
    measured = drop.states[after]
    seen: dict[float, np.ndarray] = {}  # each lag's observation, the chosen one returned as is

    def sse(lag: float) -> float:
        seen[lag] = observe(tr, model, drop, lag)
        r = ((seen[lag][after] - measured) * scale).ravel()
        r = r[np.isfinite(r)]  # gaps in the recording
        return float(r @ r)

    lag = best_lag(sse, window)
    return seen[lag], (tr.result.outcome if outcome else None), lag
