"""Choosing the leg presets per landing condition (paper Sec. V-B, V-C).

The paper's rule (Fig. 9): of the candidate friction-torque pairs, the best is the one whose
shock absorbers "compressed the most without reaching their end of travel". As a ranking:

1. by outcome class: ideal > under-used > end of travel > slid > joint touch > flip > damaged
   (the outcome codes' order; damaged only happens to the stock rigid gear);
2. among ideal or under-used landings, the larger **mean** of the two legs' peak compression
   wins (both legs' travel counts as dissipated energy; the class already guarantees that
   neither leg reached its end);
3. among end-of-travel landings, the smaller mean compression wins (the softer stop);
4. remaining ties (failures, equal compressions) go to the first candidate in the order
   listed (uphill torque, then downhill torque, then uphill angle, all ascending).

The uphill leg angle follows the paper's linear rule (37.5 deg on flat ground, 24 deg at
40 deg), continued past 40 deg (the reason for lowering it, an uphill leg meeting the ground
near 90 deg, grows with the slope) and held inside the joint's range. ``angle="optimal"``
searches a set of angles instead; ``torques="refined"`` follows the level search with a
compass search on continuous torques.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from itertools import product

import numpy as np

from slopelander.envelope.axes import MapAxes
from slopelander.envelope.maps import PRESET_FIELDS, LandingMap, model_record, results_to_fields
from slopelander.envelope.sweep import run_sweep
from slopelander.errors import SlopelanderError
from slopelander.model import ConditionError, LandingConditions, Model, Outcome, default_conditions

TORQUE_LEVELS: tuple[float, ...] = (0.56, 1.1, 1.7, 2.3)
"""Per-joint friction torque levels of Sec. V-B, N*m."""
TORQUE_RANGE: tuple[float, float] = (0.3, 3.2)
"""Bounds of the continuous torque search, N*m: 3.2 is the Sec. III sizing; 0.3 is about half
the lowest level the leg board was shown to hold (assumed)."""
REFINE_STEPS: tuple[float, ...] = (0.3, 0.15, 0.075)
"""Compass-search step per round, N*m: starts at half the level spacing, halves each round."""
ANGLE_FLAT_DEG = 37.5
ANGLE_AT_40_DEG = 24.0
ANGLE_LEVELS: tuple[float, ...] = (37.5, 33.0, 28.5, 24.0, 19.5, 15.0)
"""Uphill leg angles tried by the optimal-angle search, deg."""


class StrategyError(SlopelanderError, ValueError):
    """A preset strategy that does not make sense."""


@dataclass(frozen=True)
class Strategy:
    """How the presets of a map are chosen, and how the vehicle lands.

    ``torques``: ``fixed`` (``tau`` on every joint), ``levels`` (best pair of ``levels``) or
    ``refined`` (levels, then a continuous compass search). ``angle``: ``max`` (both legs
    at 37.5 deg), ``linear`` (paper's uphill rule) or ``optimal`` (search ANGLE_LEVELS).
    """

    name: str
    torques: str = "levels"
    tau: float = 1.7
    levels: tuple[float, ...] = TORQUE_LEVELS
    angle: str = "max"
    reverse_percent: float = 0.0
    reverse_delay: float = 0.0
    rigid: bool = False
    reverse_duration: float = math.inf
    """s the reverse thrust is held before it ends (inf: to the horizon, the maps' default)."""
    reverse_ramp: float = 0.0
    """s over which it then falls to zero (0: a step)."""

    def __post_init__(self) -> None:
        if self.torques not in ("fixed", "levels", "refined"):
            raise StrategyError(f"torques must be fixed, levels or refined, got {self.torques!r}")
        if self.angle not in ("max", "linear", "optimal"):
            raise StrategyError(f"angle must be max, linear or optimal, got {self.angle!r}")
        if not 0 <= self.reverse_percent <= 100:
            raise StrategyError(f"reverse_percent must lie within 0..100, got {self.reverse_percent}")
        try:
            LandingConditions(
                reverse_percent=self.reverse_percent,
                reverse_delay=self.reverse_delay,
                reverse_duration=self.reverse_duration,
                reverse_ramp=self.reverse_ramp,
            ).validate()
        except ConditionError as e:
            raise StrategyError(f"strategy {self.name!r}: {e}") from None

    def describe(self) -> str:
        gear = "rigid gear" if self.rigid else "FSA legs"
        if self.rigid:
            legs = ""
        elif self.torques == "fixed":
            legs = f", tau_up = tau_down = {self.tau:g} N*m"
        else:
            legs = ", best torque pair" + (
                " (continuous)"
                if self.torques == "refined"
                else " of " + "/".join(f"{v:g}" for v in self.levels) + " N*m"
            )
        angle = {
            "max": "",
            "linear": ", uphill angle 37.5->24 deg at 40 deg",
            "optimal": ", best uphill angle",
        }[self.angle]
        rvt = (
            f", {self.reverse_percent:g} % reverse thrust at impact"
            if self.reverse_percent
            else ", no thrust"
        )
        if self.reverse_percent and math.isfinite(self.reverse_duration):
            end = f"ramped to zero over {self.reverse_ramp:g} s" if self.reverse_ramp else "then stopped"
            rvt += f" held {self.reverse_duration:g} s, {end}"
        return gear + legs + angle + rvt

    def to_dict(self) -> dict:
        """The strategy as a file records it; a thrust held to the horizon (the default) leaves
        out its end, so such files read as before the thrust could end."""
        d = asdict(self)
        d["levels"] = list(self.levels)
        if not math.isfinite(self.reverse_duration):
            del d["reverse_duration"], d["reverse_ramp"]
        return d

    def with_options(
        self,
        *,
        refine: bool = False,
        optimal_angle: bool = False,
        reverse_duration: float | None = None,
        reverse_ramp: float = 0.0,
    ) -> Strategy:
        """Variants: refined torques, the best uphill angle, a reverse thrust that ends after
        ``reverse_duration`` s with a ``reverse_ramp`` s ramp (strategies with reverse thrust only)."""
        s = self
        if refine and s.torques == "levels":
            s = replace(s, torques="refined")
        if optimal_angle and s.angle == "linear":
            s = replace(s, angle="optimal")
        if reverse_duration is not None and s.reverse_percent > 0:
            s = replace(s, reverse_duration=reverse_duration, reverse_ramp=reverse_ramp)
        return s


STRATEGIES: dict[str, Strategy] = {
    s.name: s
    for s in (
        Strategy("symmetric", torques="fixed", tau=1.7),  # Fig. 8
        Strategy("asymmetric"),  # Fig. 9
        Strategy("angle", angle="linear"),  # Fig. 11, dark green
        Strategy("rvt", angle="linear", reverse_percent=100.0),  # Fig. 10
        Strategy("rigid", torques="fixed", rigid=True),  # Fig. 11, stock F450
        Strategy("rigid_rvt", torques="fixed", rigid=True, reverse_percent=100.0),
    )
}


def linear_uphill_angle(
    slope_deg: np.ndarray | float, angle_min_deg: float = 0.5, angle_max_deg: float = ANGLE_FLAT_DEG
) -> np.ndarray:
    """Paper Sec. V-C: 37.5 deg on flat ground falling linearly to 24 deg at 40 deg, continued."""
    a = ANGLE_FLAT_DEG + (ANGLE_AT_40_DEG - ANGLE_FLAT_DEG) * np.asarray(slope_deg, float) / 40.0
    return np.clip(a, angle_min_deg, angle_max_deg)


def preset_score(results: np.ndarray) -> np.ndarray:
    """Higher is better; the ranking of the module docstring as one number per landing."""
    rank = results["outcome"].astype(int)
    mean = 0.5 * (results["compression_up"] + results["compression_down"])
    mean = np.clip(np.nan_to_num(mean), 0.0, 1.0)
    key = np.where(rank <= Outcome.UNDER_USED, mean, np.where(rank == Outcome.END_OF_TRAVEL, 1.0 - mean, 0.0))
    return (int(max(Outcome)) - rank) + 0.5 * key


def _candidates(strategy: Strategy, axes: MapAxes, model: Model) -> np.ndarray:
    """Candidate presets per slope, shape (n_slopes, n_candidates, 4) in PRESET_FIELDS order."""
    lo, hi = model.params.angle_min_deg, model.params.angle_max_deg
    pairs = (
        [(strategy.tau, strategy.tau)]
        if strategy.torques == "fixed" or strategy.rigid
        else list(product(strategy.levels, strategy.levels))
    )
    n_s = axes.slopes.size
    if strategy.angle == "max" or strategy.rigid:
        angles = np.full((n_s, 1), hi)
    elif strategy.angle == "linear":
        angles = linear_uphill_angle(axes.slopes, lo, hi)[:, None]
    else:
        levels = [a for a in ANGLE_LEVELS if lo <= a <= hi]
        angles = np.tile(np.asarray(levels), (n_s, 1))
    out = np.empty((n_s, len(pairs) * angles.shape[1], 4))
    k = 0
    for tu, td in pairs:
        for a in range(angles.shape[1]):
            out[:, k] = np.column_stack([np.full(n_s, tu), np.full(n_s, td), angles[:, a], np.full(n_s, hi)])
            k += 1
    return out


def _grid(axes: MapAxes, presets: np.ndarray, strategy: Strategy) -> np.ndarray:
    """Conditions for presets of shape (n_slopes, n_speeds, n_candidates, 4)."""
    n_s, n_v, n_c, _ = presets.shape
    grid = default_conditions(n_s * n_v * n_c)
    grid["slope_deg"] = np.broadcast_to(axes.slopes[:, None, None], (n_s, n_v, n_c)).ravel()
    grid["speed"] = np.broadcast_to(axes.speeds[None, :, None], (n_s, n_v, n_c)).ravel()
    for f, name in enumerate(PRESET_FIELDS):
        grid[name] = presets[..., f].ravel()
    grid["reverse_percent"] = strategy.reverse_percent
    grid["reverse_delay"] = strategy.reverse_delay
    if strategy.reverse_percent > 0:
        grid["reverse_duration"] = strategy.reverse_duration
        grid["reverse_ramp"] = strategy.reverse_ramp
    return grid


def choose_presets(
    model: Model,
    axes: MapAxes,
    strategy: Strategy | str,
    *,
    client=None,
    progress: bool | None = None,
    chunk: int | None = None,
) -> LandingMap:
    """The map of a strategy: each cell's chosen preset and the landing it gives."""
    if isinstance(strategy, str):
        try:
            strategy = STRATEGIES[strategy]
        except KeyError:
            raise StrategyError(f"unknown strategy {strategy!r}; known: {', '.join(STRATEGIES)}") from None
    flown = model.rigid() if strategy.rigid else model
    kw = {"client": client, "progress": progress, **({"chunk": chunk} if chunk else {})}
    n_s, n_v = axes.shape
    per_slope = _candidates(strategy, axes, model)
    cand = np.broadcast_to(per_slope[:, None], (n_s, n_v, *per_slope.shape[1:]))
    res = run_sweep(_grid(axes, cand, strategy), flown, desc=strategy.name, **kw)
    res = res.reshape(n_s, n_v, cand.shape[2])
    best = np.argmax(preset_score(res), axis=-1)
    idx = np.indices((n_s, n_v))
    chosen = cand[idx[0], idx[1], best].copy()
    chosen_res = res[idx[0], idx[1], best].copy()
    evaluated = n_s * n_v * cand.shape[2]
    if strategy.torques == "refined" and not strategy.rigid:
        chosen, chosen_res, extra = _refine(flown, axes, strategy, chosen, chosen_res, kw)
        evaluated += extra
    fields = {name: chosen[..., f] for f, name in enumerate(PRESET_FIELDS)}
    fields.update(results_to_fields(chosen_res, (n_s, n_v)))
    meta = {
        "strategy": strategy.to_dict(),
        "description": strategy.describe(),
        "model": model_record(flown),
        "landings_simulated": int(evaluated),
    }
    return LandingMap(strategy.name, axes, fields, meta)


def _refine(
    model: Model, axes: MapAxes, strategy: Strategy, chosen: np.ndarray, chosen_res: np.ndarray, kw: dict
) -> tuple[np.ndarray, np.ndarray, int]:
    """Compass search on (tau_up, tau_down) from the best level pair, every cell at once."""
    n_s, n_v = axes.shape
    moves = np.array([(du, dd) for du in (-1, 0, 1) for dd in (-1, 0, 1) if du or dd], float)
    score = preset_score(chosen_res)
    evaluated = 0
    for h in REFINE_STEPS:
        cand = np.repeat(chosen[:, :, None, :], len(moves), axis=2)
        cand[..., 0:2] = np.clip(cand[..., 0:2] + h * moves, *TORQUE_RANGE)
        res = run_sweep(
            _grid(axes, cand, strategy), model, desc=f"{strategy.name} refine {h:g}", **kw
        ).reshape(n_s, n_v, len(moves))
        evaluated += res.size
        s = preset_score(res)
        k = np.argmax(s, axis=-1)
        idx = np.indices((n_s, n_v))
        better = s[idx[0], idx[1], k] > score
        chosen = np.where(better[..., None], cand[idx[0], idx[1], k], chosen)
        chosen_res = chosen_res.copy()
        chosen_res[better] = res[idx[0], idx[1], k][better]
        score = np.where(better, s[idx[0], idx[1], k], score)
    return chosen, chosen_res, evaluated
