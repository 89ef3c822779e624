"""Model vs measurement: NRMSE per state, per drop, per phase, outcome match, worst windows.

NRMSE follows the paper (Sec. IV-D): the RMS error of each state divided by that state's
range over the whole dataset (so a drop on flat ground, whose x hardly moves, is not divided
by almost zero), and the states combined with the angular ones (pitch, pitch rate) weighted x2.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from slopelander.ident.clocks import align_windows, aligned
from slopelander.ident.phases import PHASES, phase_labels
from slopelander.ident.recording import STATES, Drop
from slopelander.model import LandingConditions, Model, Outcome

WEIGHTS = np.array([1.0, 1.0, 2.0, 1.0, 1.0, 2.0])
"""Per-state weights of the combined NRMSE: angular states count twice, as in the paper."""
WINDOW = 0.05
"""s: length of the windows in which the residual's concentration is reported."""


def state_ranges(drops: list[Drop]) -> np.ndarray:
    """Range of each measured state over the dataset (floored so none is zero); gaps (NaN)
    are left out."""
    allst = np.concatenate([d.states[d.t >= 0] for d in drops])
    rng = np.nanmax(allst, axis=0) - np.nanmin(allst, axis=0)
    return np.maximum(rng, 1e-6)


def combine(per_state: np.ndarray) -> float:
    """Weighted mean over the six states (angular x2); a state with no value (NaN: every
    sample a gap) is left out."""
    ok = np.isfinite(per_state)
    if ok.all():
        return float(np.sum(WEIGHTS * per_state) / WEIGHTS.sum())
    return float(np.sum(WEIGHTS[ok] * per_state[ok]) / WEIGHTS[ok].sum()) if ok.any() else float("nan")


def masked_rms(err: np.ndarray) -> np.ndarray:
    """RMS of each column over its samples that are not gaps (NaN where a column has none)."""
    ok = np.isfinite(err)
    n = ok.sum(axis=0)
    sq = np.where(ok, err, 0.0) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(sq.sum(axis=0) / np.maximum(n, 1)), np.nan)


@dataclass(frozen=True)
class DropComparison:
    name: str
    t: np.ndarray
    measured: np.ndarray
    simulated: np.ndarray
    labels: np.ndarray
    per_state: np.ndarray
    """NRMSE of each state (after first contact)."""
    per_phase: dict[str, np.ndarray]
    """NRMSE per state in each phase present."""
    observed: Outcome | None
    predicted: Outcome | None
    conditions: LandingConditions
    lag: float = 0.0
    """s: the recording's clock against the model's, as aligned (0 when not)."""

    @property
    def nrmse(self) -> float:
        return combine(self.per_state)

    @property
    def outcome_match(self) -> bool | None:
        return None if self.observed is None else self.observed == self.predicted


@dataclass(frozen=True)
class Window:
    drop: str
    start: float
    end: float
    phase: str
    state: str
    share: float
    """Fraction of the dataset's weighted squared residual inside this window."""


@dataclass(frozen=True)
class Comparison:
    """Everything ``slopelander compare`` reports."""

    drops: list[DropComparison]
    ranges: np.ndarray

    @property
    def per_state(self) -> np.ndarray:
        return np.mean([d.per_state for d in self.drops], axis=0)

    @property
    def nrmse(self) -> float:
        return float(np.mean([d.nrmse for d in self.drops]))

    def per_phase(self) -> dict[str, float]:
        """Combined NRMSE per phase, pooled over the drops that have that phase."""
        out = {}
        for p in PHASES:
            vals = [combine(d.per_phase[p]) for d in self.drops if p in d.per_phase]
            if vals:
                out[p] = float(np.mean(vals))
        return out

    def phase_share(self) -> dict[str, float]:
        """Share of the weighted squared residual in each phase (after contact)."""
        tot = {p: 0.0 for p in PHASES}
        for d in self.drops:
            e = np.nan_to_num(((d.simulated - d.measured) / self.ranges) ** 2 * WEIGHTS).sum(axis=1)
            for i, p in enumerate(PHASES):
                tot[p] += float(e[d.labels == i].sum())
        s = sum(tot.values()) or 1.0
        return {p: v / s for p, v in tot.items()}

    def state_share(self) -> dict[str, float]:
        e = np.zeros(6)
        for d in self.drops:
            e += np.nan_to_num((((d.simulated - d.measured) / self.ranges) ** 2) * WEIGHTS)[d.t >= 0].sum(
                axis=0
            )
        return {k: float(v) for k, v in zip(STATES, e / max(e.sum(), 1e-300), strict=True)}

    def worst_windows(self, n: int = 5) -> list[Window]:
        """The ``n`` windows of :data:`WINDOW` seconds holding most of the residual."""
        cands = []
        total = 0.0
        for d in self.drops:
            e = np.nan_to_num((((d.simulated - d.measured) / self.ranges) ** 2) * WEIGHTS)
            e[d.t < 0] = 0.0
            total += float(e.sum())
            dt = float(np.median(np.diff(d.t)))
            w = max(1, round(WINDOW / dt))
            csum = np.concatenate([[0.0], np.cumsum(e.sum(axis=1))])
            starts = np.arange(0, max(1, len(d.t) - w + 1), w)
            for s in starts:
                val = csum[min(s + w, len(d.t))] - csum[s]
                seg = slice(s, min(s + w, len(d.t)))
                state = STATES[int(np.argmax(e[seg].sum(axis=0)))]
                phase = PHASES[int(np.bincount(d.labels[seg], minlength=len(PHASES)).argmax())]
                cands.append((val, d.name, float(d.t[s]), float(d.t[seg.stop - 1]), phase, state))
        cands.sort(key=lambda c: -c[0])
        total = total or 1.0
        return [Window(c[1], c[2], c[3], c[4], c[5], float(c[0] / total)) for c in cands[:n]]

    def outcome_matches(self) -> tuple[int, int]:
        known = [d for d in self.drops if d.observed is not None]
        return sum(bool(d.outcome_match) for d in known), len(known)


def compare_drop(model: Model, drop: Drop, ranges: np.ndarray, align: float = 0.0) -> DropComparison:
    """One drop's comparison; ``align``: its clock's window (:func:`align_windows`)."""
    sim, outcome, lag = aligned(model, drop, align, np.sqrt(WEIGHTS) / ranges, outcome=True)
    labels = phase_labels(drop.t, drop.states[:, 4], drop.states[:, 3], drop.conditions.slope_deg)
    err = (sim - drop.states) / ranges
    contact = drop.t >= 0
    per_state = masked_rms(err[contact])  # gaps (NaN) in the recording are left out
    per_phase = {p: masked_rms(err[labels == i]) for i, p in enumerate(PHASES) if (labels == i).any()}
    return DropComparison(
        drop.name,
        drop.t,
        drop.states,
        sim,
        labels,
        per_state,
        per_phase,
        drop.outcome,
        outcome,
        drop.conditions,
        lag,
    )


def compare(
    model: Model,
    drops: list[Drop],
    ranges: np.ndarray | None = None,
    align: Sequence[float] | None = None,
) -> Comparison:
    """Simulate every drop with ``model`` and measure the error against the recording.
    ``align``: each drop's clock window (s; default :func:`align_windows`' own)."""
    if not drops:
        raise ValueError("no drops to compare")
    ranges = state_ranges(drops) if ranges is None else ranges
    align = align_windows(drops) if align is None else align
    return Comparison([compare_drop(model, d, ranges, w) for d, w in zip(drops, align, strict=True)], ranges)
