"""Profile intervals (slopelander.ident.profile) on problems whose answer is known: a straight
line with each drop's noise mostly one shared offset, a nuisance parameter, and a cost made
piecewise (the way a landing's is) by rounding the parameter the residual sees."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander.ident.profile import coarse_scan, profile_interval

DROPS, SAMPLES = 8, 40


def _problem(rng: np.random.Generator, step: float = 0.0):
    """Residuals of y = b x + c (b, c in the unit cube) on 8 drops; ``step`` rounds b as the
    residual sees it (a piecewise-constant cost, kinks ``step`` apart)."""
    x = rng.uniform(0.2, 1.0, DROPS * SAMPLES) + np.repeat(rng.normal(0, 0.3, DROPS), SAMPLES)
    y = 0.5 * x + 0.3 + np.repeat(rng.normal(0, 0.05, DROPS), SAMPLES) + rng.normal(0, 0.005, x.size)
    groups = np.repeat(np.arange(DROPS), SAMPLES)

    def residuals(points):
        out = []
        for u in points:
            b = np.round(u[0] / step) * step if step else u[0]
            out.append(b * x + u[1] - y)
        return out

    X = np.column_stack([x, np.ones_like(x)])
    best = np.linalg.lstsq(X, y, rcond=None)[0]
    return residuals, groups, best


@pytest.mark.parametrize("step", [0.0, 0.004])
def test_profile_intervals_hold_the_truth_about_95_percent_of_the_time(step):
    """Over 120 problems the profile's interval of the slope holds 0.5 in 88-100 % of them,
    smooth or piecewise; intervals that took the 320 samples as independent (Gauss-Newton) held
    it in under half (the test would fail if the drops were not the units)."""
    rng = np.random.default_rng(11)
    held = naive = 0
    for _ in range(120):
        residuals, groups, best = _problem(rng, step)
        prof = profile_interval(residuals, best, groups, 0, span=0.02, ls_evals=20)
        held += abs(prof.centre - 0.5) <= prof.half
        r = residuals([best])[0]
        x = residuals([np.array([1.0, best[1]])])[0] - residuals([np.array([0.0, best[1]])])[0]
        X = np.column_stack([x, np.ones_like(x)])
        cov = np.linalg.inv(X.T @ X) * (r @ r) / (len(r) - 2)
        naive += abs(best[0] - 0.5) <= 1.96 * np.sqrt(cov[0, 0])
    print(f"step {step}: profile held {held}/120, independent samples {naive}/120")
    assert 0.88 <= held / 120 <= 1.0
    assert naive / 120 < 0.5


def test_the_profile_follows_the_valley_and_its_span_follows_the_interval():
    """Held at each point, the slope's profile lets the intercept settle: its minimum is the
    least-squares optimum of both (a cut with the intercept held would not be, started off it).
    The span ends between one and four times the interval's reach."""
    residuals, groups, best = _problem(np.random.default_rng(3))
    off = np.array([best[0], best[1] + 0.05])
    prof = profile_interval(residuals, off, groups, 0, span=0.3, ls_evals=20)
    cut = profile_interval(residuals, off, groups, 0, span=0.3, ls_evals=0)
    assert prof.centre == pytest.approx(best[0], abs=1e-3)
    assert abs(cut.centre - best[0]) > 0.02
    reach = abs(prof.centre - off[0]) + prof.half
    assert reach <= prof.span <= 4 * reach or prof.span == pytest.approx(0.01)


def test_the_coarse_scan_finds_the_valley_a_search_stopped_short_of():
    residuals, _, best = _problem(np.random.default_rng(5))
    short = np.array([0.95, 0.05])
    point, cost = coarse_scan(residuals, short, 0, ls_evals=20)
    r = residuals([short])[0]
    assert cost < 0.1 * float(r @ r)
    assert abs(point[0] - best[0]) <= 0.05  # the nearest of the scan's 11 points


def test_one_drop_gives_no_interval_and_says_why():
    residuals, groups, best = _problem(np.random.default_rng(1))
    prof = profile_interval(residuals, best, np.zeros_like(groups), 0, span=0.02, ls_evals=5)
    assert prof.half == np.inf and "one drop" in prof.note


def _switching(residuals, groups, period: float = 0.003, jump: float = 0.1):
    """``residuals`` with drop 0's outcome switching as the slope crosses bands ``period`` wide
    (a flip that comes and goes with a pad's radius): its residuals ``jump`` higher in every
    other band."""
    first = groups == 0

    def out(points):
        rs = residuals(points)
        for u, r in zip(points, rs, strict=True):
            if int(np.floor(u[0] / period)) % 2:
                r[first] += jump
        return rs

    return out


def test_a_profile_made_rough_by_a_switching_drop_widens_its_interval_and_says_so(monkeypatch):
    """With one drop's outcome switching along the slope the parabolas read a minimum the jumps
    placed; the profile's misfit to its parabola is then far above the interval's own rise: the
    interval is widened by it and the note says the profile is rough. Over 40 problems the
    widened intervals held the truth in 35 (rough said in 21), the same unwidened in 22; the
    smooth problems' intervals are left as they were (35 of 40, nothing said)."""
    from slopelander.ident import profile

    def run(rough: float, switching: bool) -> tuple[int, int]:
        monkeypatch.setattr(profile, "ROUGH", rough)
        rng = np.random.default_rng(5)
        held = said = 0
        for _ in range(40):
            residuals, groups, best = _problem(rng)
            if switching:
                residuals = _switching(residuals, groups)
            prof = profile_interval(residuals, best, groups, 0, span=0.02, ls_evals=20)
            held += abs(prof.centre - 0.5) <= prof.half
            said += "rough" in prof.note
        return held, said

    held, said = run(1.0, True)
    bare, _ = run(np.inf, True)
    smooth, smooth_said = run(1.0, False)
    print(f"switching: widened held {held}/40 (rough said {said}), unwidened {bare}/40; smooth {smooth}/40")
    assert held >= 34 and bare <= 26 and said >= 15
    assert smooth_said == 0
