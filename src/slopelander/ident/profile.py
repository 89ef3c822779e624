"""95 % intervals read off each parameter's profile, with the drops as the independent units.

Why: the sandwich reads the cost's slope a step either side of the optimum, and the cost of a
landing is piecewise (a foot sticks a sample sooner, a backlash gap is crossed), so that slope is
the nearest kink's; and a search that stopped short of the optimum leaves the sandwich describing
where it stopped. Drops with a hidden backlash (3.0 deg) printed 3.138 +- 0.072 deg and
2.912 +- 0.057 deg: the truth 1.5-1.9 half-widths away (benchmarks/results/2026-12-07-effect-intervals.md).

The profile fixes one parameter at a time across a span and lets the others settle (least
squares from the neighbouring point's values), so it follows the valley rather than one point of
it. Each drop's share of the cost along the profile is fitted by a parabola over the whole span,
which smooths the kinks; the minimum of the parabolas with one drop left out, for each drop in
turn, gives the jackknife's variance over drops (no refits), Student's t with drops - 1 degrees
of freedom, as the sandwich over drops uses. The interval is centred on that minimum and widened
to contain the fitted value. A coarse scan across the bounds first looks for a lower cost than
the fit's: if it finds one, the search had stopped short, and the caller refits from there.

Pure numerics on a residual function: no model, no files (tested on a linear problem whose
coverage is known)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

Residuals = Callable[[list[np.ndarray]], list[np.ndarray]]
"""Residual vectors at each of a batch of points of the unit cube."""

FINE_POINTS = 9
"""Points along a parameter's span where its profile is evaluated."""
COARSE_POINTS = 11
"""Points across the bounds where the coarse scan looks for a lower cost than the fit's."""
SPAN_MIN = 0.01
"""The narrowest half-span (share of the bounds): wider than the cost's kinks (the sandwich's
:data:`~slopelander.ident.fit.INTERVAL_STEP`)."""
SPAN_MAX = 0.25
SPAN_TRIES = 4
"""How often the span is moved and refitted to the interval it gave (its middle to the
parabolas' minimum, its half-width between one and four of the interval's): the parabola is read
where the interval lies, not about a fitted value that sits on one side of a kink."""
NUISANCE_STEP = 1e-3


@dataclass
class Profile:
    """One parameter's profile: where it was evaluated and the interval read from it."""

    index: int
    centre: float
    """The parabolas' common minimum (unit cube)."""
    half: float
    """The 95 % half-width about ``centre`` (unit cube; inf where the profile has no minimum)."""
    span: float
    points: list[tuple[float, float]] = field(default_factory=list)
    """(unit value, cost) along the fine profile."""
    note: str = ""
    lowest: np.ndarray | None = None
    """The full point (unit cube) of the lowest cost the profile met."""
    lowest_cost: float = math.inf

    def half_about(self, u: float) -> float:
        """The half-width about ``u`` (the fitted value) that holds this interval."""
        return abs(self.centre - u) + self.half


class _Settle:
    """The other parameters polished by least squares with one parameter held: each point once."""

    def __init__(self, residuals: Residuals, n: int, k: int, ls_evals: int, tick: Callable[[int], None]):
        self.residuals, self.n, self.k, self.ls_evals, self.tick = residuals, n, k, ls_evals, tick
        self.others = [i for i in range(n) if i != k]

    def full(self, theta: float, v: np.ndarray) -> np.ndarray:
        u = np.empty(self.n)
        u[self.k] = theta
        u[self.others] = v
        return u

    def at(self, theta: float, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The full point and its residual: the others from ``v0`` polished with ``theta`` held."""
        start = self.full(theta, v0)
        r0 = self.residuals([start])[0]
        self.tick(1)
        if not self.others or self.ls_evals <= 0:
            return start, r0
        from scipy.optimize import least_squares

        cache: dict[bytes, np.ndarray] = {np.asarray(v0, dtype=float).tobytes(): r0}

        def fun(v: np.ndarray) -> np.ndarray:
            key = np.asarray(v, dtype=float).tobytes()
            if key not in cache:
                cache[key] = self.residuals([self.full(theta, v)])[0]
                self.tick(1)
            return cache[key]

        def jac(v: np.ndarray) -> np.ndarray:
            r = fun(v)
            pts, steps = [], []
            for i in range(len(v)):
                step = NUISANCE_STEP if v[i] + NUISANCE_STEP <= 1.0 else -NUISANCE_STEP
                w = np.array(v, dtype=float)
                w[i] += step
                pts.append(self.full(theta, w))
                steps.append(step)
            cols = self.residuals(pts)
            self.tick(len(pts))
            return np.column_stack([(c - r) / s for c, s in zip(cols, steps, strict=True)])

        v0 = np.clip(np.asarray(v0, dtype=float), 1e-6, 1 - 1e-6)
        least_squares(  # its points are all in the cache; the best of them is kept
            fun, v0, jac=jac, bounds=(0.0, 1.0), x_scale="jac", max_nfev=self.ls_evals, xtol=1e-8, ftol=1e-10
        )
        best = min(cache, key=lambda key: float(cache[key] @ cache[key]))
        v = np.frombuffer(best, dtype=float)
        return self.full(theta, v), cache[best]


Points = dict[float, tuple[np.ndarray, np.ndarray]]
"""Along a profile: each held value's full point and residual."""


def _march(settle: _Settle, u: np.ndarray, thetas: Sequence[float]) -> Points:
    """The profile at each of ``thetas``, marching outward from ``u``'s own value on each side
    so that each point starts from its inner neighbour's settled values."""
    k, here = settle.k, float(u[settle.k])
    out: Points = {}
    up = sorted(t for t in thetas if t >= here)
    down = sorted((t for t in thetas if t < here), reverse=True)
    for side in (up, down):
        v = np.delete(u, k)
        for t in side:
            point, r = settle.at(float(t), v)
            out[float(t)] = (point, r)
            v = np.delete(point, k)
    return out


def coarse_scan(
    residuals: Residuals, u: np.ndarray, k: int, ls_evals: int, tick: Callable[[int], None] = lambda n: None
) -> tuple[np.ndarray, float]:
    """The lowest point of parameter ``k``'s profile on :data:`COARSE_POINTS` across its bounds
    (and ``u`` itself): where a search that stopped short should go on from."""
    settle = _Settle(residuals, len(u), k, ls_evals, tick)
    grid = np.linspace(0.0, 1.0, COARSE_POINTS)
    r0 = residuals([np.asarray(u, dtype=float)])[0]
    best = (np.asarray(u, dtype=float), float(r0 @ r0))
    for point, r in _march(settle, np.asarray(u, dtype=float), grid).values():
        c = float(r @ r)
        if c < best[1]:
            best = (point, c)
    return best


def _parabolas(thetas: np.ndarray, shares: np.ndarray, centre0: float) -> tuple[np.ndarray, np.ndarray]:
    """Each drop's share of the cost as a + b d + c d^2 in d = theta - centre0 (least squares
    over the span): the (drops, 3) coefficients and the total's."""
    d = thetas - centre0
    X = np.column_stack([np.ones_like(d), d, d * d])
    coef, *_ = np.linalg.lstsq(X, shares, rcond=None)  # (3, drops)
    return coef.T, coef.sum(axis=1)


def _jackknife_var(coef: np.ndarray, b: float, c: float) -> float:
    """The variance of the profile's minimum by the jackknife over drops, each left-out minimum
    read off the other drops' parabolas (no refits): (n - 1) / n times the spread of the n
    minima. The sandwich of the drops' slopes is the same to first order but leaves out each
    drop's own curvature (its leverage): on a line whose drops differ in reach it held the truth
    in 86 % of 120 problems, this in the 95 % asked (tests/ident/test_profile.py); a minimum a
    drop's removal leaves without one (the rest not convex) counts as infinitely far."""
    n = len(coef)
    rest_c = c - coef[:, 2]
    if np.any(rest_c <= 0):
        return math.inf
    minima = -(b - coef[:, 1]) / (2 * rest_c)
    return float((n - 1) / n * np.sum((minima - minima.mean()) ** 2))


ROUGH = 1.0
"""A profile whose cost departs from its parabola by more than this share of the interval's
own rise is rough: kinks (a backlash's gap crossed), or a drop whose outcome switches along it
(round pads hidden: a flip on a 34.6 deg roof came and went within 0.2 mm of pad radius, its
NRMSE 0.014 <-> 0.14)."""


def _rough(result: Profile, d: np.ndarray, total: np.ndarray, abc: tuple[float, float, float]) -> None:
    """Widen ``result`` where the profile's total cost departs from its parabola (RMS misfit m)
    by more than :data:`ROUGH` times the rise the interval stands for (c h^2): the minimum can
    then move as far as a rise of m, so the half-width becomes sqrt(h^2 + m / c), and the note
    says so. A smooth profile (m ~ 0) keeps its interval."""
    a, b, c = abc
    misfit = float(np.sqrt(np.mean((total - (a + b * d + c * d * d)) ** 2)))
    rise = c * result.half**2
    if c > 0 and misfit > ROUGH * rise:
        widened = math.sqrt(result.half**2 + misfit / c)
        result.note = (
            f"rough profile (off its parabola by {misfit / max(rise, 1e-300):.1f}x the interval's rise: "
            f"kinks, or an outcome switching), interval widened {widened / max(result.half, 1e-300):.1f}x"
        )
        result.half = widened


def profile_interval(
    residuals: Residuals,
    u: np.ndarray,
    groups: np.ndarray,
    k: int,
    span: float,
    ls_evals: int,
    tick: Callable[[int], None] = lambda n: None,
) -> Profile:
    """Parameter ``k``'s 95 % interval from its profile about the optimum ``u`` (unit cube):
    ``groups`` gives the drop of each residual, ``span`` the first half-span (e.g. twice the
    sandwich's half-width), ``ls_evals`` the other parameters' polish at each point."""
    from scipy.stats import t as student

    u = np.asarray(u, dtype=float)
    ids, inverse = np.unique(groups, return_inverse=True)
    n = len(ids)
    if n < 2:
        return Profile(k, float(u[k]), math.inf, span, note="one drop: no spread between drops to read")
    quantile = float(student.ppf(0.975, n - 1))
    settle = _Settle(residuals, len(u), k, ls_evals, tick)
    span = float(min(max(span, SPAN_MIN), SPAN_MAX))
    seen: Points = {}
    flat = "the profile has no minimum across its span"
    lone = "one drop alone makes the profile's minimum (left out, the rest have none)"
    result = Profile(k, float(u[k]), math.inf, span, note=flat)
    mid = float(u[k])  # the span's middle: moved to the parabolas' minimum until it holds it
    for _ in range(SPAN_TRIES + 1):
        lo, hi = max(0.0, mid - span), min(1.0, mid + span)
        thetas = [t for t in np.linspace(lo, hi, FINE_POINTS) if float(t) not in seen]
        seen.update(_march(settle, u, thetas))
        inside = sorted(t for t in seen if lo - 1e-12 <= t <= hi + 1e-12)
        shares = np.array([np.bincount(inverse, weights=seen[t][1] ** 2, minlength=n) for t in inside])
        coef, (a0, b, c) = _parabolas(np.array(inside), shares, mid)
        points = [(t, float(seen[t][1] @ seen[t][1])) for t in inside]
        var = _jackknife_var(coef, b, c) if c > 0 else math.inf
        if not math.isfinite(var):  # no minimum, or none once some drop is left out: wider
            result = Profile(k, mid, math.inf, span, points, flat if c <= 0 else lone)
            if span >= SPAN_MAX:
                break
            span = min(2 * span, SPAN_MAX)
            continue
        d0 = float(np.clip(-b / (2 * c), lo - mid, hi - mid))
        result = Profile(k, mid + d0, quantile * math.sqrt(var), span, points)
        _rough(result, np.array(inside) - mid, shares.sum(axis=1), (a0, b, c))
        held = abs(d0) <= span / 2
        if held and (result.half <= span <= 4 * result.half or (span <= SPAN_MIN and result.half < span)):
            break
        if span >= SPAN_MAX and result.half > span:
            break
        mid, span = mid + d0, float(min(max(2 * result.half, SPAN_MIN), SPAN_MAX))
    low = min(seen, key=lambda t: float(seen[t][1] @ seen[t][1]))
    result.lowest, result.lowest_cost = seen[low][0], float(seen[low][1] @ seen[low][1])
    return result
