"""Measuring each leg's current → friction-torque curve on the bench, and fitting it.

The procedure (docs/legs-build.md, "Calibration"): every leg carries a lever of known length
with a known mass, held at its mark by a peg. For each mass, every trial loosens the legs,
clamps them from loose at a current (as a landing's preset clamps), pulls the pegs and reads
the joint angles: a leg that slipped needs more current, one that held less. The currents
bracket, then bisect, each leg's slip current to within a step (2 mA); the curve so far
predicts the first current of the next mass. Every mass is measured ``repeats`` times, in
alternating order (light to heavy, then heavy to light), so hysteresis shows as a spread.

The fit per leg is current as a quadratic (or, with fewer than four masses, linear) function
of torque — the torques are exact, the currents carry the bracket's error — by least squares,
with its covariance giving the curve's uncertainty. The fit is refused, with the reason, when
a mass's slip currents spread more than a few steps over the repeats (hysteresis, a skipping
gear), when the points do not follow a smooth rising curve, or when a leg never holds.
"""

from __future__ import annotations

import datetime
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from slopelander.legs.bench import MARK_DEG, Bench, G
from slopelander.legs.calibration import Calibration, LegCurve
from slopelander.legs.driver import LegBoard, Operation
from slopelander.legs.errors import LegBoardError, TorqueOutOfRange
from slopelander.legs.messages import N_LEGS

TABLE_POINTS = 9


class CalibrationRefused(LegBoardError):  # noqa: N818 (names the user reads)
    """The measurements do not make a calibration to fly on; ``reasons`` says why, per leg."""

    def __init__(self, reasons: Sequence[str]) -> None:
        self.reasons = list(reasons)
        super().__init__("calibration refused:\n  " + "\n  ".join(self.reasons))


@dataclass(frozen=True)
class Procedure:
    """The bench and the search: masses (kg) on a lever (m), how often, how finely."""

    masses_kg: tuple[float, ...]
    lever_m: float
    lever_moment_nm: float = 0.0  # the bare lever's own torque at the mark
    repeats: int = 3
    step_ma: int = 2
    margin_ma: int = 6  # a one-sided bracket looks this far past its end (doubling each time)
    watch_s: float = 1.0  # after the peg is pulled, watch the angle this long
    slip_deg: float = 0.5  # a drop larger than this is a slip
    max_ma: int = 175  # the board's limit (legfw.config.Config.max_target_ma)
    clamp_timeout_s: float = 40.0
    max_spread_ma: float = 6.0  # one mass's slip currents over the repeats
    max_rms_nm: float = 0.06  # points about the fitted curve
    max_trials: int = 12  # per mass and run

    def __post_init__(self) -> None:
        if len(self.masses_kg) < 3 or any(not (m > 0 and math.isfinite(m)) for m in self.masses_kg):
            raise ValueError("give at least 3 masses, each a positive number of kg")
        if len(set(self.masses_kg)) != len(self.masses_kg):
            raise ValueError("the masses must all differ")
        if not (self.lever_m > 0 and math.isfinite(self.lever_m)):
            raise ValueError("the lever length must be a positive number of metres")
        if self.repeats < 2:
            raise ValueError("repeat every mass at least twice (hysteresis shows only in repeats)")

    def torque_nm(self, mass_kg: float) -> float:
        return mass_kg * G * self.lever_m + self.lever_moment_nm


@dataclass(frozen=True)
class SlipPoint:
    """One leg's slip current for one mass in one run: held at ``high_ma``, slipped at ``low_ma``."""

    leg: int
    run: int
    torque_nm: float
    low_ma: int
    high_ma: int

    @property
    def current_ma(self) -> float:
        return 0.5 * (self.low_ma + self.high_ma)


@dataclass(frozen=True)
class LegFit:
    """Current (mA) as a polynomial in torque (N·m), with its covariance."""

    leg: int
    coeffs: tuple[float, ...]  # c = coeffs[0] + coeffs[1]·τ + coeffs[2]·τ²
    cov: tuple[tuple[float, ...], ...]
    torque_range: tuple[float, float]
    residual_rms_nm: float
    spread_ma: float
    points: tuple[SlipPoint, ...] = field(repr=False)

    def current_ma(self, torque_nm: float) -> float:
        return sum(c * torque_nm**k for k, c in enumerate(self.coeffs))

    def slope(self, torque_nm: float) -> float:
        """dc/dτ, mA per N·m."""
        return sum(k * c * torque_nm ** (k - 1) for k, c in enumerate(self.coeffs) if k)

    def sigma_nm(self, torque_nm: float) -> float:
        """1σ of the fitted curve at ``torque_nm``, as torque (the current's σ over the slope)."""
        x = np.array([torque_nm**k for k in range(len(self.coeffs))])
        var = float(x @ np.array(self.cov) @ x)
        return math.sqrt(max(var, 0.0)) / self.slope(torque_nm)

    def torques(self, n: int = TABLE_POINTS) -> list[float]:
        lo, hi = self.torque_range
        return [lo + (hi - lo) * k / (n - 1) for k in range(n)]

    @property
    def uncertainty_nm(self) -> float:
        """The curve's 95 % band (2σ), its widest over the calibrated range."""
        return max(2.0 * self.sigma_nm(t) for t in self.torques(25))

    def curve(self) -> LegCurve:
        torques = self.torques()
        return LegCurve(tuple(self.current_ma(t) for t in torques), tuple(torques))


# ---- measuring ------------------------------------------------------------------------
def measure(
    board: LegBoard,
    bench: Bench,
    proc: Procedure,
    guess: Calibration,
    log: Callable[[str], None] = print,
) -> list[SlipPoint]:
    """Run the procedure; every leg's slip point for every mass and run."""
    points: list[SlipPoint] = []
    order = sorted(proc.masses_kg)
    for run in range(proc.repeats):
        masses = order if run % 2 == 0 else order[::-1]
        for mass in masses:
            tau = proc.torque_nm(mass)
            found = _one_mass(board, bench, proc, guess, points, run, tau)
            points += found
            log(
                f"run {run + 1}/{proc.repeats}, {mass:g} kg ({tau:.3f} N·m): slip at "
                + ", ".join(f"leg {p.leg} {p.current_ma:.1f} mA" for p in found)
            )
    _wait(board, bench, board.start_loosen(timeout=proc.clamp_timeout_s))
    return points


def _predict(points: list[SlipPoint], guess: Calibration, leg: int, tau: float) -> float:
    mine = [p for p in points if p.leg == leg]
    torques = {p.torque_nm for p in mine}
    if len(torques) >= 2:
        a, b = np.polyfit([p.torque_nm for p in mine], [p.current_ma for p in mine], 1)
        return float(a * tau + b)
    curve = guess.legs[leg]
    try:
        return guess.current_for(leg, min(max(tau, curve.min_torque_nm), curve.max_torque_nm))
    except TorqueOutOfRange:
        return curve.current_ma[-1]


def _one_mass(
    board: LegBoard,
    bench: Bench,
    proc: Procedure,
    guess: Calibration,
    points: list[SlipPoint],
    run: int,
    tau: float,
) -> list[SlipPoint]:
    """Bracket every leg's slip current for one mass: each trial clamps from loose, as a
    landing's preset does, at a current that brackets then bisects."""
    bench.hang([tau] * N_LEGS)
    current = {
        leg: max(0, min(proc.max_ma, round(_predict(points, guess, leg, tau)))) for leg in range(N_LEGS)
    }
    slipped: dict[int, int | None] = dict.fromkeys(range(N_LEGS))  # highest current that slipped
    held: dict[int, int | None] = dict.fromkeys(range(N_LEGS))  # lowest current that held
    reach = dict.fromkeys(range(N_LEGS), proc.margin_ma)  # how far to look past a one-sided bracket
    found: list[SlipPoint] = []
    active = list(range(N_LEGS))
    for _trial in range(proc.max_trials):
        if not active:
            break
        _wait(board, bench, board.start_loosen(active, timeout=proc.clamp_timeout_s))
        bench.hold(active)
        _wait(
            board,
            bench,
            board.start_currents({leg: current[leg] for leg in active}, timeout=proc.clamp_timeout_s),
        )
        bench.release(active)
        bench.wait(proc.watch_s)
        status = board.query(timeout=5.0)
        for leg in list(active):
            if MARK_DEG - status.legs[leg].angle_deg > proc.slip_deg:
                slipped[leg] = current[leg]
            else:
                held[leg] = current[leg]
            lo, hi = slipped[leg], held[leg]
            if lo is not None and hi is not None:
                if hi - lo <= proc.step_ma:
                    found.append(SlipPoint(leg, run, tau, lo, hi))
                    active.remove(leg)
                    continue
                current[leg] = (lo + hi + 1) // 2
            elif lo is not None:  # only slipped so far: look higher, further each time
                if lo >= proc.max_ma:
                    raise CalibrationRefused(
                        [
                            f"leg {leg} never held {tau:.3f} N·m, not even at the board's limit "
                            f"{proc.max_ma} mA: a slipping gear or a stripped screw, or a mass "
                            "heavier than the legs are for"
                        ]
                    )
                current[leg] = min(proc.max_ma, lo + reach[leg])
                reach[leg] *= 2
            else:  # only held so far: look lower
                if hi <= 0:
                    raise CalibrationRefused([f"leg {leg} held {tau:.3f} N·m with no current at all"])
                current[leg] = max(0, hi - reach[leg])
                reach[leg] *= 2
    if active:
        raise CalibrationRefused(
            [
                f"leg {leg}: no slip current found for {tau:.3f} N·m in {proc.max_trials} trials"
                for leg in active
            ]
        )
    return sorted(found, key=lambda p: p.leg)


def _wait(board: LegBoard, bench: Bench, op: Operation) -> None:
    while op.check() is None:
        bench.wait(0.05)
        board.poll()


# ---- fitting --------------------------------------------------------------------------
def fit_leg(leg: int, points: Sequence[SlipPoint], proc: Procedure) -> LegFit:
    """The least-squares curve of one leg's points (see the module's docstring)."""
    mine = [p for p in points if p.leg == leg]
    tau = np.array([p.torque_nm for p in mine])
    cur = np.array([p.current_ma for p in mine])
    degree = 2 if len(set(tau.tolist())) >= 4 else 1
    X = np.vander(tau, degree + 1, increasing=True)
    coef, *_ = np.linalg.lstsq(X, cur, rcond=None)
    resid = cur - X @ coef
    dof = max(1, len(cur) - (degree + 1))
    # the scatter the points show, but never less than the bracket's own (a step, uniform)
    s2 = max(float(resid @ resid) / dof, proc.step_ma**2 / 12.0)
    cov = s2 * np.linalg.inv(X.T @ X)
    spread = 0.0
    for t in set(tau.tolist()):
        at = cur[tau == t]
        spread = max(spread, float(at.max() - at.min()))
    fit = LegFit(
        leg,
        tuple(float(c) for c in coef),
        tuple(tuple(float(v) for v in row) for row in cov),
        (float(tau.min()), float(tau.max())),
        0.0,
        spread,
        tuple(mine),
    )
    slopes = np.array([fit.slope(t) for t in fit.torques(25)])
    rms = (
        float(np.sqrt(np.mean((resid / np.maximum(slopes.mean(), 1e-9)) ** 2)))
        if slopes.mean() > 0
        else math.inf
    )
    return LegFit(fit.leg, fit.coeffs, fit.cov, fit.torque_range, rms, spread, fit.points)


def problems(fit: LegFit, proc: Procedure) -> list[str]:
    """Why this leg's fit must not be flown on (empty if it may)."""
    out = []
    leg = fit.leg
    if fit.spread_ma > proc.max_spread_ma:
        out.append(
            f"leg {leg}: one mass's slip currents spread {fit.spread_ma:.1f} mA over the repeats "
            f"(at most {proc.max_spread_ma:g}): hysteresis in the screw or the stack, or a gear that skips"
        )
    if any(fit.slope(t) <= 0 for t in fit.torques(25)):
        out.append(f"leg {leg}: the fitted current does not rise with torque over the range measured")
    elif fit.residual_rms_nm > proc.max_rms_nm:
        out.append(
            f"leg {leg}: the points lie {fit.residual_rms_nm:.3f} N·m (rms) off a smooth curve "
            f"(at most {proc.max_rms_nm:g})"
        )
    return out


def fit_all(points: Sequence[SlipPoint], proc: Procedure) -> list[LegFit]:
    """Every leg's fit; :class:`CalibrationRefused` with every reason if any leg's is poor."""
    fits = [fit_leg(leg, points, proc) for leg in range(N_LEGS)]
    reasons = [r for f in fits for r in problems(f, proc)]
    if reasons:
        raise CalibrationRefused(reasons)
    return fits


def document(fits: Sequence[LegFit], proc: Procedure, board_id: str, firmware: str) -> dict:
    """The calibration file's content (format: docs/legs-build.md, "The calibration file")."""
    legs = []
    for f in fits:
        curve = f.curve()
        legs.append(
            {
                "leg": f.leg,
                "current_ma": [round(c, 2) for c in curve.current_ma],
                "torque_nm": [round(t, 4) for t in curve.torque_nm],
                "uncertainty_nm": round(f.uncertainty_nm, 4),
                "fit": {
                    "current_ma_from_torque": [round(c, 5) for c in f.coeffs],
                    "residual_rms_nm": round(f.residual_rms_nm, 4),
                    "spread_ma": round(f.spread_ma, 2),
                },
                "points": [
                    {
                        "run": p.run,
                        "torque_nm": round(p.torque_nm, 4),
                        "slipped_ma": p.low_ma,
                        "held_ma": p.high_ma,
                    }
                    for p in f.points
                ],
            }
        )
    return {
        "provenance": "measured",
        "board_id": board_id,
        "measured": {
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "firmware": firmware,
            "method": "slip of a mass on a lever, each trial clamped from loose, bracketed and bisected "
            "(slopelander legs calibrate)",
            "masses_kg": list(proc.masses_kg),
            "lever_m": proc.lever_m,
            "lever_moment_nm": proc.lever_moment_nm,
            "repeats": proc.repeats,
            "step_ma": proc.step_ma,
        },
        "units": {"current": "mA", "torque": "N*m"},
        "legs": legs,
    }
