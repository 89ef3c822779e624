"""Which physical effect is missing: refit each candidate, test it on drops the fit did not see.

Cross-fitting over drops: the drops are split into ``folds`` groups (stratified by slope); for
each group, the base model and the base plus each candidate are identified on the other drops
and predict that group's. Every drop is thus predicted by fits that did not see it. Before the
candidates, the base itself is refitted from its optimum with the same budget a candidate gets
(the control): a candidate must beat the base given as much search, not a base that stopped
sooner. A candidate is named **missing** when its per-drop held-out gains pass a sign-flip
test over drops at the 5 % level, corrected for the number of candidates tried
(:mod:`slopelander.ident.evidence`), and, for each base-physics alternative that explains part of
the residual (:mod:`slopelander.ident.base_alternatives`: the base laws' own shape freed), beats
it on held-out drops or still passes the test refitted on top of it; if not, the data cannot tell
it from a difference in the base physics, and it is not named. Otherwise the verdict compares the
held-out residual with the recordings' noise floor: at the floor, nothing is missing (nothing
larger than what these drops can see); clearly above it, something is, but not among these
candidates, or too little of it to tell with these drops.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from slopelander.ident.base_alternatives import BASE_ALTERNATIVES
from slopelander.ident.clocks import align_windows
from slopelander.ident.compare import compare, state_ranges
from slopelander.ident.evidence import (
    MIN_GAIN,
    SignFlipTest,
    names_missing,
    noise_floor,
    sign_flip_test,
    weighted_mse,
)
from slopelander.ident.fit import (
    DEFAULT_BOUNDS,
    INTERVAL_WORDS,
    INTERVALS,
    PAPER_SEVEN,
    FitError,
    FitParam,
    FitResult,
    Identifier,
    Problem,
    effect_of,
    make_param,
    resolve_params,
    scan,
    windows,
)
from slopelander.ident.optimizers import CMA
from slopelander.ident.recording import STATES, Drop
from slopelander.model import Model, UserEffect
from slopelander.model.effects import EffectError

BUILTIN_CANDIDATES: dict[str, tuple[str, ...]] = {
    "leg_flex": ("flex_stiffness", "flex_damping"),
    "downhill_torque_growth": ("factor_tau",),
    "downhill_friction_growth": ("factor_mu",),
}
"""Built-in candidate effects and the parameters a refit identifies with them."""
NEUTRAL: dict[str, float] = {"factor_tau": 0.0, "factor_mu": 0.0}
"""Values at which a candidate's parameter leaves the model as it was: the refit starts there,
so it begins at the base model's optimum."""
ALPHA = 0.05
"""Level of the sign-flip test over drops."""
FOLDS = 2
"""Cross-fitting groups: each drop is predicted by fits on the other groups' drops."""
ABOVE_FLOOR = 1.2
"""A held-out residual above this multiple of the noise floor is more than noise: an effect
adding more than sqrt(1.2^2 - 1) = 0.66 floors (in quadrature) lifts it above. (On control
sets the base's held-out NRMSE, fitted on half the drops, read 0.95-1.12 floors.)"""
STALL = 8
"""Generations without a lower cost after which a diagnosis's CMA-ES search stops
(:class:`~slopelander.ident.optimizers.CMA` ``stall``): the base's refits and the candidates'
start at an optimum, and where nothing is missing their searches spent the whole budget
confirming it (benchmarks/results/2026-12-06-diagnose-speed.md)."""
BUILTIN_NOT_NESTED = (
    "built-in: no value of {} within its bounds switches it off, so it is refitted from their centre "
    "and may end above the base"
)
"""Why a built-in candidate is not nested (a user's own effect is told to declare ``neutral``)."""
NOT_AMONG = 1.5
"""An excess beyond the floor of more than this many floors that no candidate explains reads
"missing, but not among these candidates"; a smaller one "too small to tell"."""


@dataclass(frozen=True)
class Candidate:
    name: str
    params: tuple[str, ...]
    user: UserEffect | None = None

    def add_to(self, model: Model) -> Model:
        if self.user is not None:
            return model.with_user_effect(self.user)
        return model.with_effects(self.name)


def candidates_for(model: Model, user_effects: list[UserEffect] | None = None) -> list[Candidate]:
    """The built-in candidates the model lacks, plus each user effect."""
    out = [Candidate(n, p) for n, p in BUILTIN_CANDIDATES.items() if n not in model.effects]
    names = {e.name for e in model.user_effects}
    for e in user_effects or []:
        if e.name not in names:
            out.append(Candidate(e.name, tuple(e.parameters), e))
    return out


@dataclass
class CandidateResult:
    candidate: Candidate
    screening: float
    """Extra share of the base residual the candidate's direction removes beyond re-tuning the
    base's parameters (linearised)."""
    fits: list[FitResult] = field(default_factory=list)
    """One per cross-fitting group (and repeat)."""
    heldout: np.ndarray | None = None
    """Per drop: NRMSE predicted by the fits that did not see the drop."""
    heldout_mse: np.ndarray | None = None
    """Per drop: the fit's weighted mean square error, predicted likewise."""
    p: float = math.nan
    """Family-wise p-value of its held-out gains (sign-flip max-T over drops)."""
    nested: bool | None = None
    """At its neutral values it is the base model (None: not checked)."""
    nested_note: str = ""
    sensitivity: np.ndarray | None = None
    """Per drop: NRMSE of the change the screening step makes (where the effect acts)."""
    restarted: int = 0
    """Groups whose fit never left the candidate's neutral values while another group's did,
    searched again from the centre of its bounds."""

    @property
    def validation_nrmse(self) -> float:
        return float(np.mean(self.heldout)) if self.heldout is not None else math.nan

    @property
    def train_nrmse(self) -> float:
        return float(np.mean([f.train_nrmse for f in self.fits]))

    final: FitResult | None = None
    """Refitted on every drop once named missing (the estimate; the groups' fits decided)."""

    def values(self) -> dict[str, float]:
        """The fitted values: from the refit on every drop when there is one, else the mean of
        the groups' fits."""
        if self.final is not None:
            return {p: float(self.final.values[p]) for p in self.candidate.params}
        return {p: float(np.mean([f.values[p] for f in self.fits])) for p in self.candidate.params}

    def spread(self) -> dict[str, tuple[float, float]]:
        """Lowest and highest value over the cross-fitting groups' fits (each on other drops)."""
        return {
            p: (min(f.values[p] for f in self.fits), max(f.values[p] for f in self.fits))
            for p in self.candidate.params
        }


SETTLE_CONDITIONS: dict[str, tuple[str, str]] = {
    "slope_deg": ("slope", "deg"),
    "speed": ("impact speed", "m/s"),
    "torque": ("torques", "N*m"),
}
"""The drops' conditions a user can choose, by which :meth:`Diagnosis.settle` tells the kind of
drop that would settle a candidate (``torque``: the mean of the uphill and downhill joints')."""


def condition_value(drop: Drop, key: str) -> float:
    """A drop's condition by :data:`SETTLE_CONDITIONS` key."""
    c = drop.conditions
    return 0.5 * (c.tau_up + c.tau_down) if key == "torque" else float(getattr(c, key))


@dataclass(frozen=True)
class Settle:
    """The kind of drop on which a candidate's gain shows most consistently, and how many of them
    a test would need (``condition`` empty: drops like all of these)."""

    condition: str
    unit: str
    low: float
    high: float
    drops: list[str]
    """These drops of that kind."""
    needed: int
    """Drops of that kind a one-sided test at the diagnosis's level (Bonferroni over the
    candidates) would need to pass with 80 % power, were their observed gain and spread the truth."""
    more: int
    """``needed`` less those already there."""
    gains: np.ndarray
    """The per-drop log gains of those drops."""

    @property
    def kind(self) -> str:
        if not self.condition:
            return "drops like these"
        return f"drops at {self.condition} {self.low:.3g}-{self.high:.3g} {self.unit}"

    def to_dict(self) -> dict:
        return {
            "condition": self.condition or None,
            "low": None if not self.condition else self.low,
            "high": None if not self.condition else self.high,
            "unit": self.unit or None,
            "drops": self.drops,
            "mean_log_gain": float(np.mean(self.gains)),
            "sd_log_gain": float(np.std(self.gains, ddof=1)) if len(self.gains) > 1 else 0.0,
            "needed": self.needed,
            "more": self.more,
        }


@dataclass
class Diagnosis:
    base: list[FitResult]
    """The base model's control refits, one per group (the comparator of every candidate)."""
    results: list[CandidateResult]
    """Refitted candidates, best held-out gain first; then screened-out ones (no fits)."""
    base_heldout: np.ndarray
    base_heldout_mse: np.ndarray
    drops: list[Drop]
    test: SignFlipTest | None
    floor: float | None
    """NRMSE the recordings' declared noise alone leaves (None: not declared)."""
    folds: int = FOLDS
    alpha: float = ALPHA
    final: FitResult | None = None
    """The missing candidate refitted on every drop: its values and their intervals over drops."""
    alternatives: list[CandidateResult] = field(default_factory=list)
    """Base-physics alternatives refitted like candidates once one passed the test (not candidates:
    never named, not in the test's family; :mod:`slopelander.ident.base_alternatives`)."""
    on_top: dict[str, CandidateResult] = field(default_factory=dict)
    """By alternative: the candidate that passed refitted with it (base + alternative + candidate),
    when it did not beat the alternative alone."""
    seed: int = 0

    @property
    def base_validation(self) -> float:
        return float(np.mean(self.base_heldout))

    @property
    def base_train(self) -> float:
        return float(np.mean([f.train_nrmse for f in self.base]))

    def gain(self, r: CandidateResult) -> float:
        """Relative fall of the held-out NRMSE from the base model's."""
        return 1.0 - r.validation_nrmse / self.base_validation

    @property
    def fitted(self) -> list[CandidateResult]:
        return [r for r in self.results if r.fits]

    @property
    def passed(self) -> CandidateResult | None:
        """The candidate whose held-out gains pass the test (named missing unless a base-physics
        alternative explains the residual as well: :attr:`missing`)."""
        fitted = {r.candidate.name: r for r in self.fitted}
        heldout = {n: (r.validation_nrmse, r.p) for n, r in fitted.items()}
        name = names_missing(heldout, self.base_validation, self.floor, self.alpha)
        return None if name is None else fitted[name]

    @property
    def missing(self) -> CandidateResult | None:
        m = self.passed
        return None if m is None or self.base_physics(m) is not None else m

    def beats(self, r: CandidateResult, a: CandidateResult) -> float:
        """p of a one-sided sign-flip test of log(a's held-out error / r's) over drops: ``r``
        explains these drops better than the alternative ``a``."""
        return float(sign_flip_test(self.log_gains(r) - self.log_gains(a), self.alpha, self.seed).p[0])

    def beyond(self, a: CandidateResult) -> tuple[float, float] | None:
        """The passed candidate refitted on top of alternative ``a``: its held-out gain over ``a``
        (relative fall of the NRMSE) and the p of its per-drop gains over ``a``'s (one-sided
        sign-flip test); None when not refitted."""
        t = self.on_top.get(a.candidate.name)
        if t is None or t.heldout_mse is None:
            return None
        g = self.log_gains(t) - self.log_gains(a)
        return 1.0 - t.validation_nrmse / a.validation_nrmse, float(
            sign_flip_test(g, self.alpha, self.seed).p[0]
        )

    def base_physics(self, r: CandidateResult) -> tuple[CandidateResult, float] | None:
        """The base-physics alternative that explains ``r`` away, with the p that failed, or None.
        An alternative lowering the held-out NRMSE by at least :data:`MIN_GAIN` stops ``r`` unless
        ``r`` beats it on held-out drops (:meth:`beats`) or, refitted on top of it, still lowers
        its NRMSE by :data:`MIN_GAIN` and passes the test over drops (:meth:`beyond`; not refitted:
        stops it). An effect that only absorbed a departure of the base laws explains nothing once
        the freed law is in; a real one still does, on whichever drops it acts."""
        worst = None
        for a in self.alternatives:
            if a.heldout_mse is None or r.heldout_mse is None or self.gain(a) < MIN_GAIN:
                continue
            if self.beats(r, a) <= self.alpha:
                continue
            more = self.beyond(a)
            if more is not None and more[0] >= MIN_GAIN and more[1] <= self.alpha:
                continue
            p = 1.0 if more is None else more[1]
            if worst is None or p > worst[1]:
                worst = (a, p)
        return worst

    def evidence(self, r: CandidateResult) -> str:
        t = self.test
        if t is None:
            return "not tested"
        how = "all" if t.exact else "random"
        better = int(np.sum(r.heldout_mse < self.base_heldout_mse)) if r.heldout_mse is not None else 0
        return (
            f"p = {r.p:.3g} over {t.patterns} {how} sign flips of {len(self.drops)} drops, "
            f"corrected for {len(self.fitted)} candidates; better on {better} of "
            f"{len(self.drops)} held-out drops"
        )

    @property
    def visible(self) -> float | None:
        """Smallest NRMSE an effect must add (in quadrature) to lift the held-out residual
        above the noise floor's threshold: what "nothing missing" can vouch for."""
        return None if self.floor is None else self.floor * math.sqrt(ABOVE_FLOOR**2 - 1.0)

    @property
    def excess(self) -> float | None:
        """NRMSE the held-out residual has beyond the noise floor (in quadrature)."""
        if self.floor is None:
            return None
        return math.sqrt(max(self.base_validation**2 - self.floor**2, 0.0))

    def hint(self, r: CandidateResult, n: int = 3) -> str:
        """Which of these drops the candidate acts on most: more drops like them would show it."""
        if r.sensitivity is None or not np.any(r.sensitivity > 0):
            return f"{r.candidate.name} changes none of these drops"
        order = np.argsort(-r.sensitivity)[:n]
        where = ", ".join(
            f"{self.drops[i].name} ({self.drops[i].conditions.slope_deg:.0f} deg, "
            f"{self.drops[i].conditions.speed:.1f} m/s, torques {self.drops[i].conditions.tau_up:.2g}/"
            f"{self.drops[i].conditions.tau_down:.2g} N*m)"
            for i in order
        )
        return f"{r.candidate.name} acts most on {where}: more drops like these would show it"

    def verdict(self) -> str:
        text = self._verdict()
        t = self.test
        if t is not None and t.exact and 1.0 / t.patterns > self.alpha:
            text += (
                f" (with {len(self.drops)} drops no candidate can pass the test: the smallest p is "
                f"1/{t.patterns} > {self.alpha:g}; give at least 5 drops)"
            )
        return text

    def _refit_short(self) -> str:
        """A warning when the named candidate's refit on all drops ends above the noise floor's
        threshold: its intervals describe where its search stopped, not the optimum (round pads
        hidden: a refit at 3.4 floors printed a radius of 0.0580 +- 0.0008 m against 0.040)."""
        if self.final is None or not self.floor:
            return ""
        ratio = self.final.train_nrmse / self.floor
        if ratio <= ABOVE_FLOOR:
            return ""
        again = any(w.startswith("the refit ended at") for w in getattr(self.final, "warnings", []))
        return (
            f"; but that refit ends at {ratio:.1f}x the noise floor (NRMSE {self.final.train_nrmse:.4f}"
            + (", searched again from a scan of its own values too" if again else "")
            + "): its search stopped short or more is missing, and the values and intervals hold "
            "only where it stopped (try --refit-from-centre or more --cma-evals)"
        )

    def _verdict(self) -> str:
        m = self.missing
        vis = f"{self.visible:.4f}" if self.visible is not None else "an unknown amount"
        floor = f"{self.floor:.4f}" if self.floor is not None else None
        if m is not None:
            vals = ", ".join(f"{k} = {v:.4g}" for k, v in m.values().items())
            if self.final is not None:
                vals = ", ".join(
                    f"{k} = {self.final.values[k]:.4g} +- {self.final.ci95[k]:.2g}"
                    for k in m.candidate.params
                )
                how = INTERVAL_WORDS[self.final.intervals]
                clocks = ", each clock free within its window" if self.final.lags else ""
                # what the intervals' own reading said of the candidate's values (a rough profile,
                # one drop alone making a minimum): a user weighs the interval by it
                notes = [
                    w for w in self.final.warnings if any(w.startswith(f"{k}: ") for k in m.candidate.params)
                ]
                vals += f" (refitted on all {len(self.drops)} drops{clocks}; 95 % intervals {how}"
                vals += "".join(f"; {w}" for w in notes) + ")"
                vals += self._refit_short()
            return (
                f"missing: {m.candidate.name} (held-out NRMSE {self.base_validation:.4f} -> "
                f"{m.validation_nrmse:.4f}, {100 * self.gain(m):.0f} % lower; {self.evidence(m)}; {vals})"
            )
        told = self.passed
        confused = None if told is None else self.base_physics(told)
        if told is not None and confused is not None:
            a, p = confused
            more = self.beyond(a)
            top = (
                f"added to {a.candidate.name}, {told.candidate.name} lowers it {100 * more[0]:+.0f} % more, "
                f"p = {p:.3g}"
                if more is not None
                else f"not refitted with {a.candidate.name}"
            )
            return (
                f"missing, but the data cannot tell {told.candidate.name} from a difference in the base "
                f"physics ({a.candidate.name}, {a.candidate.user.description if a.candidate.user else ''}): "
                f"{told.candidate.name} lowers the held-out NRMSE {100 * self.gain(told):.0f} % "
                f"({self.evidence(told)}), {a.candidate.name} {100 * self.gain(a):.0f} %; {top}; not named "
                "(drops where the two differ would tell them apart)"
            )
        best = max(self.fitted, key=self.gain, default=None)
        tried = (
            f"best candidate {best.candidate.name}: {100 * self.gain(best):+.1f} %, {self.evidence(best)}"
            if best is not None
            else "no candidate refitted"
        )
        if floor is None:
            return (
                f"nothing missing among these candidates ({tried}); the recordings declare no noise "
                "(meta.noise), so whether the residual is more than noise cannot be said"
            )
        ratio = self.base_validation / self.floor if self.floor else math.inf
        excess = self.excess or 0.0
        if ratio <= ABOVE_FLOOR:
            return (
                f"nothing missing: the held-out NRMSE {self.base_validation:.4f} is at the noise floor "
                f"{floor} ({ratio:.2f}x): nothing larger than {vis} NRMSE is missing (more would lift "
                f"it above {ABOVE_FLOOR:g}x the floor); no candidate helps on drops it did not see ({tried})"
            )
        if excess > NOT_AMONG * self.floor:
            why = "no candidate explains it"
            if best is not None and self.gain(best) >= MIN_GAIN:
                why = (
                    f"no candidate passes the test, though {best.candidate.name} lowers it "
                    f"{100 * self.gain(best):.0f} % on held-out drops"
                )
            return (
                f"missing, but not among these candidates: the held-out NRMSE {self.base_validation:.4f} "
                f"is {ratio:.1f}x the noise floor {floor} ({excess:.4f} beyond it), and {why} ({tried})"
            )
        hint = f"; {self.hint(best)}" if best is not None else ""
        return (
            f"too small to tell with these drops: the held-out NRMSE {self.base_validation:.4f} is "
            f"{ratio:.2f}x the noise floor {floor} ({excess:.4f} beyond it, less than "
            f"{NOT_AMONG:g} floors), and no candidate's gain holds over enough drops ({tried}){hint}"
        )

    # --------------------------------------------------------------- machine-readable verdict
    @property
    def kind(self) -> str:
        """The verdict as one word, the same rules as :meth:`verdict`: ``missing`` (a candidate
        named), ``base_physics`` (one passed the test but does not beat a base-physics alternative),
        ``nothing_missing`` (at the noise floor), ``not_among`` (far above the floor, no
        candidate explains it), ``too_small`` (above the floor by less than that), ``unknown``
        (no candidate named and no noise declared: nothing to measure the residual against)."""
        if self.missing is not None:
            return "missing"
        if self.passed is not None:
            return "base_physics"
        if self.floor is None:
            return "unknown"
        ratio = self.base_validation / self.floor if self.floor else math.inf
        if ratio <= ABOVE_FLOOR:
            return "nothing_missing"
        if (self.excess or 0.0) > NOT_AMONG * self.floor:
            return "not_among"
        return "too_small"

    def log_gains(self, r: CandidateResult) -> np.ndarray:
        """Per drop: log(base held-out MSE / the candidate's), the statistic the test reads."""
        if r.heldout_mse is None:
            return np.zeros(len(self.drops))
        return np.log(self.base_heldout_mse / np.maximum(r.heldout_mse, 1e-300))

    def drops_needed(self, r: CandidateResult, power: float = 0.8) -> int | None:
        """Drops like these that a one-sided test of the candidate's per-drop gains would need to
        pass at the test's level (corrected for the candidates tried, Bonferroni) with ``power``,
        were the observed mean gain and its spread the truth: ((z_a + z_power) sd / mean)^2.
        None when the observed mean gain is not positive (more drops would not show it)."""
        return self._needed(self.log_gains(r), power)

    def _needed(self, g: np.ndarray, power: float = 0.8) -> int | None:
        """((z_a + z_power) sd / mean)^2 drops of gains like ``g``, at least ``len(g)``."""
        from statistics import NormalDist

        mean, sd = float(np.mean(g)), float(np.std(g, ddof=1)) if len(g) > 1 else 0.0
        if not mean > 0:
            return None
        if sd == 0.0:
            return len(g)
        alpha = self.alpha / max(1, len(self.fitted))
        z = NormalDist().inv_cdf(1 - alpha) + NormalDist().inv_cdf(power)
        return max(len(g), math.ceil((z * sd / mean) ** 2))

    def settle(self, r: CandidateResult) -> Settle | None:
        """Which kind of drop would settle ``r`` soonest: of the drops' conditions (slope, impact
        speed, torques), the half of these drops (lowest or highest in one condition) on which
        its per-drop gains need the fewest drops to pass at the observed mean and spread, when
        that is fewer than drops like all of these need. A user then drops where the effect
        shows, not at random. None when no kind of drop shows a positive mean gain."""
        g = self.log_gains(r)
        n = len(g)
        best = None
        every = self._needed(g)
        if every is not None:
            best = Settle("", "", math.nan, math.nan, [d.name for d in self.drops], every, every - n, g)
        half = (n + 1) // 2
        for key, (label, unit) in SETTLE_CONDITIONS.items():
            vals = np.array([condition_value(d, key) for d in self.drops])
            if half < 3 or np.ptp(vals) <= 1e-9 * max(1.0, float(np.max(np.abs(vals)))):
                continue
            order = np.argsort(vals, kind="stable")
            for idx in (order[:half], order[n - half :]):
                need = self._needed(g[idx])
                if need is None or (best is not None and need >= best.needed):
                    continue
                lo, hi = float(vals[idx].min()), float(vals[idx].max())
                names = [self.drops[i].name for i in sorted(idx)]
                best = Settle(label, unit, lo, hi, names, need, need - len(idx), g[idx])
        return best

    def alike(self, r: CandidateResult, within: float = 0.8) -> list[tuple[CandidateResult, float]]:
        """The other refitted candidates whose held-out gain reaches ``within`` of ``r``'s, each
        with the correlation of their per-drop gains with ``r``'s (near 1: they correct the same
        drops the same way, and these drops cannot tell the two mechanisms apart)."""
        g = self.log_gains(r)
        out = []
        for o in self.fitted:
            if o is r or not self.gain(o) >= within * self.gain(r) or self.gain(r) <= 0:
                continue
            h = self.log_gains(o)
            corr = float(np.corrcoef(g, h)[0, 1]) if np.std(g) > 0 and np.std(h) > 0 else math.nan
            out.append((o, corr))
        return out

    def to_dict(self) -> dict:
        """Everything the verdict rests on, for a program to read (``diagnose --json``)."""
        best = self.missing or max(self.fitted, key=self.gain, default=None)

        def cand(r: CandidateResult) -> dict:
            d = {
                "name": r.candidate.name,
                "screening": float(r.screening),
                "nested": r.nested,
                "nested_note": r.nested_note or None,
            }
            if r.fits:
                mse = r.heldout_mse
                better = int(np.sum(mse < self.base_heldout_mse)) if mse is not None else 0
                d.update(
                    train_nrmse=r.train_nrmse,
                    heldout_nrmse=r.validation_nrmse,
                    gain=self.gain(r),
                    p=r.p,
                    better_on_drops=better,
                    values=r.values(),
                    drops_needed=self.drops_needed(r),
                )
            return d

        out = {
            "verdict": self.kind,
            "text": self.verdict(),
            "drops": [d.name for d in self.drops],
            "base": {"train_nrmse": self.base_train, "heldout_nrmse": self.base_validation},
            "noise_floor_nrmse": self.floor,
            "alpha": self.alpha,
            "candidates": [cand(r) for r in self.results],
            "best": None if best is None else best.candidate.name,
        }
        if best is not None:
            st = self.settle(best)
            out["settle"] = None if st is None else st.to_dict()
            out["alike"] = [
                {"name": o.candidate.name, "gain": self.gain(o), "gain_correlation": c}
                for o, c in self.alike(best)
            ]
        if self.alternatives:
            told = self.passed
            out["base_alternatives"] = [
                {
                    "name": a.candidate.name,
                    "heldout_nrmse": a.validation_nrmse,
                    "gain": self.gain(a),
                    "values": a.values(),
                    "beaten_p": None if told is None else self.beats(told, a),
                    "on_top": None
                    if (more := self.beyond(a)) is None
                    else {"gain": more[0], "p": more[1], "values": self.on_top[a.candidate.name].values()},
                }
                for a in self.alternatives
            ]
            confused = None if told is None else self.base_physics(told)
            out["base_physics"] = (
                None if confused is None else {"name": confused[0].candidate.name, "p": confused[1]}
            )
        m = self.missing
        if m is not None and self.final is not None:
            out["missing"] = {
                "name": m.candidate.name,
                "values": {k: float(self.final.values[k]) for k in m.candidate.params},
                "ci95": {k: float(self.final.ci95[k]) for k in m.candidate.params},
                "intervals": self.final.intervals,
                "refit_nrmse": float(self.final.train_nrmse),
                "warnings": list(self.final.warnings),
            }
        return out

    def weighing(self) -> str:
        """What the evidence weighs, in numbers a user can act on: the best candidate's gain and p,
        how many drops of the kind it acts on would settle it, and the candidates that explain the
        residual nearly as well."""
        best = self.missing or max(self.fitted, key=self.gain, default=None)
        if best is None:
            return ""
        lines = []
        need = self.drops_needed(best)
        name = best.candidate.name
        if self.missing is None:
            if need is None:
                lines.append(
                    f"{name} does not help on average on drops it did not see: more would not show it"
                )
            else:
                st = self.settle(best)
                assert st is not None  # a positive mean gain over all drops: "drops like these" at least
                head = f"{name}: gain {100 * self.gain(best):+.1f} %, p {best.p:.3g}; "
                power = f"pass the {self.alpha:g} level with 80 % power at their observed gain and spread"
                if st.condition:
                    lines.append(
                        f"{head}its gain is most consistent on {st.kind} ({', '.join(st.drops)}): about "
                        f"{st.more} more such drops would settle it ({st.needed} of them {power}; "
                        f"{need} drops like all of these)"
                    )
                else:
                    lines.append(
                        f"{head}about {st.more} more drops like these (now {len(self.drops)}) would settle "
                        f"it ({need} {power}; no condition shows it more consistently)"
                    )
        for o, corr in self.alike(best):
            how = "" if math.isnan(corr) else f", per-drop gains correlated {corr:+.2f} with {name}'s"
            lines.append(f"{o.candidate.name} explains nearly as much: gain {100 * self.gain(o):+.1f} %{how}")
        for a in self.alternatives:
            more = self.beyond(a)
            top = (
                "" if more is None else f"; {name} added to it: {100 * more[0]:+.1f} % more, p {more[1]:.3g}"
            )
            lines.append(
                f"{a.candidate.name} (the base physics' shape freed, not a mechanism): gain "
                f"{100 * self.gain(a):+.1f} %; {name} over it: p {self.beats(best, a):.3g}{top}"
            )
        return "\n".join(lines)

    def table(self) -> str:
        lines = [
            "| rank | candidate | screening | train NRMSE | held-out NRMSE | gain | p "
            f"| fitted (range over {self.folds} groups) |",
            "|---:|---|---:|---:|---:|---:|---:|---|",
            f"| - | (base) | - | {self.base_train:.4f} | {self.base_validation:.4f} | - | - | - |",
        ]
        for i, r in enumerate(self.results, 1):
            name = r.candidate.name + ("" if r.nested is not False else " (not nested)")
            if r.fits:
                spread = r.spread()
                vals = ", ".join(
                    f"{k} {v:.4g} [{spread[k][0]:.3g}..{spread[k][1]:.3g}]" for k, v in r.values().items()
                )
                lines.append(
                    f"| {i} | {name} | {100 * r.screening:.0f} % | {r.train_nrmse:.4f} "
                    f"| {r.validation_nrmse:.4f} | {100 * self.gain(r):+.1f} % | {r.p:.3g} | {vals} |"
                )
            else:
                lines.append(f"| {i} | {name} | {100 * r.screening:.0f} % | not refitted | | | | |")
        for a in self.alternatives:
            lines.append(
                f"| - | {a.candidate.name} (base physics) | - | {a.train_nrmse:.4f} "
                f"| {a.validation_nrmse:.4f} | {100 * self.gain(a):+.1f} % | - | "
                + ", ".join(f"{k} {v:.4g}" for k, v in a.values().items())
                + " |"
            )
        if self.floor is not None:
            lines.append(f"\nnoise floor (the recordings' declared noise alone): NRMSE {self.floor:.4f}")
        for r in self.results:
            if r.nested is False:
                lines.append(f"{r.candidate.name} is not nested: {r.nested_note}")
        again = [f"{r.candidate.name} ({r.restarted})" for r in self.results if r.restarted]
        if again:
            lines.append(
                "searched again from the centre of the bounds (groups whose search stayed at 'off' "
                f"while another group's left it): {', '.join(again)}"
            )
        return "\n".join(lines)


def neutral_values(cand: Candidate) -> dict[str, float]:
    """Values at which the candidate leaves the model as it was: the built-ins' known ones, a
    user effect's declared ``neutral`` values."""
    out = {n: NEUTRAL[n] for n in cand.params if n in NEUTRAL}
    if cand.user is not None:
        out.update({n: p.neutral for n, p in cand.user.parameters.items() if p.neutral is not None})
    return out


STUCK = 1e-3
"""A candidate's fitted parameter within this share of its bounds' range of its neutral value
has not left "off"."""


def stuck_at_neutral(values: dict[str, float], extra: list[FitParam], neutral: dict[str, float]) -> bool:
    """Every candidate parameter that has a neutral value ended at it (and there is one)."""
    named = [p for p in extra if p.name in neutral]
    return bool(named) and all(abs(p.unit(values[p.name]) - p.unit(neutral[p.name])) <= STUCK for p in named)


def candidate_params(
    model: Model, cand: Candidate, base_params: list[FitParam], bounds: dict[str, tuple[float, float]]
) -> list[FitParam]:
    declared = {}
    if cand.user is not None:
        declared = {n: (p.low, p.high) for n, p in cand.user.parameters.items() if p.bounded}
    extra = []
    for n in cand.params:
        b = bounds.get(n, declared.get(n, DEFAULT_BOUNDS.get(n)))
        if b is None:
            raise FitError(f"candidate {cand.name!r}: parameter {n!r} needs bounds ({n}=LOW:HIGH)")
        extra.append(make_param(n, *b))
    return [*base_params, *extra]


@dataclass
class Screening:
    share: float
    """Extra share of the base residual the candidate's change removes beyond the base
    parameters' own directions (linearised least squares)."""
    sensitivity: np.ndarray
    """Per drop: NRMSE of the change (how strongly the candidate acts on that drop)."""
    nested: bool
    note: str


def _per_drop(prob: Problem, r: np.ndarray) -> np.ndarray:
    """Split a residual vector into drops and give each drop's root mean square (its NRMSE as
    the fit weighs it)."""
    out, i = [], 0
    n = len(prob.drops)
    for d in prob.drops:
        k = int((d.t >= 0).sum()) * 6
        seg = r[i : i + k]
        out.append(math.sqrt(float(seg @ seg) * n))
        i += k
    return np.array(out)


def screen(
    base_model: Model,
    drops: list[Drop],
    cands: list[Candidate],
    base_params: list[FitParam],
    ranges: np.ndarray,
    bounds: dict[str, tuple[float, float]],
    align: list[float] | None = None,
) -> dict[str, Screening]:
    """Cheap signature test: switch each candidate on (a tenth of its range from "off", or at
    the centre of its bounds) and measure how much more of the base residual a least-squares
    combination of that change and the base parameters' own directions removes than those
    directions alone (linearised: a secant per direction), and on which drops it acts. Also
    checks that the candidate at its neutral values is the base model. Two simulations per
    candidate and drop, and one per base parameter and drop."""
    base_prob = Problem(base_model, drops, [], ranges, align)
    r = base_prob.residuals([])
    rr = float(r @ r)
    # what re-tuning the base's own parameters could remove (linearised): a candidate earns
    # only what it removes beyond that, as in its refit, where the base parameters move too
    tuned = Problem(base_model, drops, base_params, ranges, align)
    u0 = np.array([p.unit(base_model.parameter(p.name)) for p in base_params])
    cols = []
    for i in range(len(base_params)):
        step = 0.02 if u0[i] + 0.02 <= 1.0 else -0.02
        v = u0.copy()
        v[i] += step
        cols.append((tuned.residuals(v) - r) / step)
    Jb = np.column_stack(cols) if cols else np.zeros((len(r), 0))

    def removed(M: np.ndarray) -> float:
        if M.shape[1] == 0:
            return 0.0
        x, *_ = np.linalg.lstsq(M, -r, rcond=None)
        rest = r + M @ x
        return 1.0 - float(rest @ rest) / rr

    by_base = removed(Jb)
    out = {}
    for c in cands:
        params = candidate_params(base_model, c, [], bounds)
        prob = Problem(c.add_to(base_model), drops, params, ranges, align)
        # a small step from "off" where the effect has an off value, else the bounds' centre
        off = neutral_values(c)
        u = [min(1.0, p.unit(off[p.name]) + 0.1) if p.name in off else 0.5 for p in params]
        d = prob.residuals(u) - r
        share = max(0.0, removed(np.column_stack([Jb, d])) - by_base) if rr > 0 else 0.0
        missing = [p.name for p in params if p.name not in off]
        if missing and c.user is None:
            nested, note = False, BUILTIN_NOT_NESTED.format(", ".join(missing))
        elif missing:
            nested, note = False, f"no neutral value for {', '.join(missing)} (declare neutral=...)"
        else:
            gap = prob.residuals([p.unit(off[p.name]) for p in params]) - r
            size = math.sqrt(float(gap @ gap))
            nested = size <= 1e-9 * max(math.sqrt(rr), 1e-12)
            note = (
                ""
                if nested
                else (
                    f"at its neutral values it differs from the base by {size:.3g} NRMSE: write it so that "
                    "at them it returns exactly what the model would (read the model's own values with the "
                    "state accessors, e.g. state.ground_stiffness(ctx) and state.ground_damping(ctx) for a "
                    "normal-force law, not constants; docs/effects.md, 'Parameters')"
                )
            )
        out[c.name] = Screening(share, _per_drop(prob, d), nested, note)
    return out


def residual_signature(prob: Problem, u: np.ndarray) -> dict[str, float]:
    """Share of the squared residual per state: which states the base model gets wrong."""
    r = prob.residuals(u).reshape(-1, len(STATES))
    e = (r**2).sum(axis=0)
    return dict(zip(STATES, (e / max(e.sum(), 1e-300)).tolist(), strict=True))


def fold_splits(
    drops: list[Drop], folds: int = FOLDS, repeats: int = 1, seed: int = 0
) -> list[tuple[list[int], list[int]]]:
    """(training, held-out) index lists: each repeat splits the drops into ``folds`` groups,
    stratified by slope (each group spans the slopes), and holds out each group in turn."""
    n = len(drops)
    if not 2 <= folds <= n:
        raise FitError(f"need 2..{n} cross-fitting groups for {n} drops (got {folds})")
    if n - math.ceil(n / folds) < 1:
        raise FitError(f"{n} drops are too few to hold out a group of them")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(max(1, repeats)):
        order = np.argsort([d.conditions.slope_deg + 1e-6 * rng.random() for d in drops], kind="stable")
        group = np.empty(n, dtype=int)
        for start in range(0, n, folds):
            block = order[start : start + folds]
            group[block] = rng.permutation(folds)[: len(block)]
        for g in range(folds):
            held = sorted(np.flatnonzero(group == g).tolist())
            if held:
                out.append((sorted(np.flatnonzero(group != g).tolist()), held))
    return out


def _heldout(
    fits: list[FitResult], splits, drops: list[Drop], ranges: np.ndarray, align: list[float]
) -> tuple[np.ndarray, np.ndarray]:
    """Per drop: NRMSE and weighted MSE predicted by the fits that did not see it (averaged
    over repeats), each drop's clock aligned within its window ``align``."""
    n = len(drops)
    nrmse, mse, count = np.zeros(n), np.zeros(n), np.zeros(n)
    for f, (_, held) in zip(fits, splits, strict=True):
        c = compare(f.model, [drops[i] for i in held], ranges, [align[i] for i in held])
        for i, dc in zip(held, c.drops, strict=True):
            nrmse[i] += dc.nrmse
            mse[i] += weighted_mse(dc.per_state)
            count[i] += 1
    return nrmse / count, mse / count


@dataclass
class CrossFit:
    """What every fit of one diagnosis shares: the drops and their (training, held-out) splits,
    the states' ranges, the base model's fitted parameters and bounds, the base's search and a
    refit's (the control's and each candidate's: the refit budget, near its start)."""

    model: Model
    drops: list[Drop]
    splits: list[tuple[list[int], list[int]]]
    ranges: np.ndarray
    base_params: list[FitParam]
    bounds: dict[str, tuple[float, float]]
    search: Identifier
    refit: Identifier

    @property
    def seed(self) -> int:
        return self.search.seed

    def fit(self, ident: Identifier, k: int, **changes: object) -> FitResult:
        """``ident`` fitted on group ``k``'s training drops (its held-out ones validate it),
        seeded for the group."""
        tr, va = self.splits[k]
        one = ident.with_(seed=self.seed + k, **changes)
        return one.fit([self.drops[i] for i in tr], [self.drops[i] for i in va]).result_  # type: ignore[return-value]

    def heldout(self, fits: list[FitResult]) -> tuple[np.ndarray, np.ndarray]:
        return _heldout(fits, self.splits, self.drops, self.ranges, windows(self.drops, self.search.align_s))


def _base_and_control(cf: CrossFit) -> tuple[list[FitResult], list[FitResult]]:
    """Per group: the base model's fit, and the control, the base searched again from its
    optimum with a candidate's budget (the comparator: a candidate must beat the base given as
    much search)."""
    base, control = [], []
    for k in range(len(cf.splits)):
        b = cf.fit(cf.search, k)
        base.append(b)
        control.append(cf.fit(cf.refit, k, start=b.values))
    return base, control


def _screened(c: Candidate, sc: Screening) -> CandidateResult:
    """A candidate as its screening left it (not refitted yet)."""
    return CandidateResult(c, sc.share, nested=sc.nested, nested_note=sc.note, sensitivity=sc.sensitivity)


def _refit_candidate(
    cf: CrossFit, res: CandidateResult, base: list[FitResult], control: list[FitResult], guard: bool = False
) -> None:
    """The candidate refitted with the base's parameters in every group, from the group's base
    optimum with the candidate off, and its held-out errors (into ``res``). ``guard`` (a base
    alternative, which a named candidate must beat): every group is searched again from the
    centre of the alternative's bounds, the lower kept; a guard whose search stops short lets
    a candidate through that only absorbs a base difference (a joint departure, seed 5: the
    alternative ended at 0.08 at 15.9 rad/s against the truth's 0.5 at 5)."""
    c = res.candidate
    params = candidate_params(cf.model, c, cf.base_params, cf.bounds)
    extra, neutral = params[len(cf.base_params) :], neutral_values(c)
    centre = {p.name: p.value(0.5) for p in extra}
    # a parameter without a neutral value starts at the centre of its bounds: its shipped or
    # declared value would be the truth of a synthetic proof
    off = {**centre, **neutral}
    cand = cf.refit.with_(model=c.add_to(cf.model), params=params)
    for k in range(len(cf.splits)):
        # also the control's optimum with the candidate off: a nested candidate's training cost
        # cannot end above the control's
        res.fits.append(cf.fit(cand, k, start={**base[k].values, **off}, also=[{**control[k].values, **off}]))
    stuck = [guard or stuck_at_neutral(f.values, extra, neutral) for f in res.fits]
    if any(stuck) and (guard or not all(stuck)):
        # some groups' searches left "off" and others never did: from the base optimum the effect
        # can need the base parameters to move with it (a valley no step of the search enters).
        # Those are searched again from the centre of the candidate's bounds, a start no drop
        # chose; the first answer is kept if still best on the group's own training drops.
        # (Another group's values are not used as a start: they were fitted on this group's
        # held-out drops.)
        for k in np.flatnonzero(stuck):
            again = {"start": {**base[k].values, **centre}, "also": [res.fits[k].values]}
            res.fits[k] = cf.fit(cand, int(k), **again)
            res.restarted += 1
    res.heldout, res.heldout_mse = cf.heldout(res.fits)


def _test(
    fitted: list[CandidateResult], base_mse: np.ndarray, alpha: float, seed: int
) -> SignFlipTest | None:
    """The sign-flip test of the refitted candidates' per-drop held-out gains; sets each one's p."""
    if not fitted:
        return None
    gains = np.array([np.log(base_mse / np.maximum(r.heldout_mse, 1e-300)) for r in fitted])
    test = sign_flip_test(gains, alpha, seed)
    for r, p in zip(fitted, test.p, strict=True):
        r.p = float(p)
    return test


def _final(
    cf: CrossFit,
    m: CandidateResult,
    intervals: str = "profile",
    floor: float | None = None,
    base: list[FitResult] | None = None,
) -> FitResult:
    """The missing candidate refitted on every drop, from the groups' mean: the decision used
    held-out drops, the estimate uses them all; its intervals of the kind ``intervals``. Each
    drop's clock is free within its window, one frame where the drop records none (unless the
    user set one): a lag of 2 ms read as a hidden 3.0 deg backlash of 3.14 and 3.23 deg, the
    truth outside the interval (benchmarks/results/2026-12-08-effect-intervals.md). A refit
    ending above :data:`ABOVE_FLOOR` times the noise ``floor`` searches once more from the
    best point of a scan of the candidate's own values (:func:`~slopelander.ident.fit.scan`), the
    rest where it stopped, at the model's own values or at the ``base`` fits' mean; the lower
    is kept."""
    align = cf.refit.align_s
    if align is None:
        align = align_windows(cf.drops, frame=True)
    mean = {p.name: float(np.mean([f.values[p.name] for f in m.fits])) for p in m.fits[0].params}
    one = cf.refit.with_(
        model=m.candidate.add_to(cf.model),
        params=list(m.fits[0].params),
        seed=cf.seed,
        start=mean,
        also=[f.values for f in m.fits],
        sigma=0.1,
        starts=None,
        intervals=intervals,
        align_s=align,
    )
    out = one.fit(cf.drops).result_
    if floor and out is not None and out.train_nrmse > ABOVE_FLOOR * floor:
        # far above the floor: the search may have stopped beside a thin valley (round pads'
        # radius and inset trade); the candidate's own values scanned across their bounds (the
        # rest where the refit ended), one more run from the best point, the lower kept
        names = [p for p in m.candidate.params if p in out.values]
        anchors = [out.values, {}]  # where it stopped; the base at the model's own values
        if base:
            anchors.append({k: float(np.mean([f.values[k] for f in base])) for k in base[0].values})
        best, _ = scan(one, cf.drops, names, anchors)
        again = one.with_(start=best, also=[out.values], seed=cf.seed + 1).fit(cf.drops).result_
        note = (
            f"the refit ended at {out.train_nrmse / floor:.1f}x the noise floor; searched again from "
            f"the best of a scan of {', '.join(names)}: {again.train_nrmse / floor:.1f}x"
        )
        out = again if again is not None and again.cost < out.cost else out
        out.warnings.append(note)
    return out  # type: ignore[return-value]


def _on_top(cf: CrossFit, told: CandidateResult, alt: CandidateResult) -> CandidateResult:
    """The candidate ``told`` refitted on the base plus alternative ``alt`` (every parameter
    free): what it explains that the freed base law does not. Each group's search starts from the
    group's fit of ``alt`` with the candidate off and also tries its fit of ``told`` with the
    alternative off (both fitted on the group's training drops), so neither explanation must be
    found again within the refit budget."""
    assert alt.candidate.user is not None
    c = told.candidate
    model = cf.model.with_user_effect(alt.candidate.user)
    with_alt = candidate_params(cf.model, alt.candidate, cf.base_params, cf.bounds)
    params = candidate_params(model, c, with_alt, cf.bounds)

    def off(cand: Candidate, extra: list[FitParam]) -> dict[str, float]:
        return {**{p.name: p.value(0.5) for p in extra}, **neutral_values(cand)}

    c_off = off(c, params[len(with_alt) :])
    a_off = off(alt.candidate, with_alt[len(cf.base_params) :])
    ident = cf.refit.with_(model=c.add_to(model), params=params)
    res = CandidateResult(c, math.nan)
    for k in range(len(cf.splits)):
        start = {**alt.fits[k].values, **c_off}
        res.fits.append(cf.fit(ident, k, start=start, also=[{**told.fits[k].values, **a_off}]))
    res.heldout, res.heldout_mse = cf.heldout(res.fits)
    return res


def _alternatives(model: Model, effects: list[UserEffect]) -> list[Candidate]:
    """The base-physics alternatives that can be added to ``model`` (not already in it, no clash
    of names or seams with its own user effects)."""
    out = []
    for e in effects:
        try:
            model.with_user_effect(e)
        except EffectError:
            continue
        if e.name not in {u.name for u in model.user_effects}:
            out.append(Candidate(e.name, tuple(e.parameters), e))
    return out


def diagnose(
    model: Model,
    drops: list[Drop],
    *,
    user_effects: list[UserEffect] | None = None,
    names: list[str] | None = None,
    bounds: dict[str, tuple[float, float]] | None = None,
    folds: int = FOLDS,
    repeats: int = 1,
    refits: int | None = None,
    refit_evals: int = 200,
    refit_from_centre: bool = False,
    alpha: float = ALPHA,
    stall: int | None = STALL,
    final_intervals: str = "profile",
    base_alternatives: list[UserEffect] | None = None,
    **search: object,
) -> Diagnosis:
    """Find the effect ``model`` is missing to explain ``drops``.

    ``names``: the base model's fitted parameters (default the paper's seven it has);
    ``folds``: cross-fitting groups, ``repeats``: how many times the drops are split into them
    (a drop's held-out error is averaged over repeats); ``refits``: how many of the screened
    candidates get the expensive refit (default all); ``refit_evals``: the global search's
    budget of each refit (the control's, a candidate's); ``refit_from_centre``: each refit's
    budget is shared between a run from the base optimum and one from the centre of the bounds
    (the base optimum can sit far from the answer when the base model bent its parameters to
    mimic the missing effect); ``alpha``: the test's level; ``stall``: a CMA-ES search (the
    default optimizer, or a :class:`~slopelander.ident.optimizers.CMA` given without its own
    ``stall``) stops after this many generations without a lower cost (None: every search runs
    its whole budget, as before 2026-12-06). ``final_intervals``: the kind of 95 % interval of a named
    candidate's refit on every drop (default ``"profile"``; ``"jackknife"``: one least-squares refit per
    drop left out, :func:`slopelander.ident.fit.jackknife`). ``base_alternatives``: the base physics'
    freed shapes a candidate that passes the test must beat on held-out drops to be named (default
    :data:`~slopelander.ident.base_alternatives.BASE_ALTERNATIVES`; ``[]``: none, the rule before
    2026-12-07). ``search``: the base fit's settings,
    those of an :class:`~slopelander.ident.fit.Identifier` (``seed``, ``cma_evals`` 400,
    ``ls_evals`` 20, ``optimizer``, ``workers``, ``client``, ``progress``); ``seed`` also seeds
    the splits, the test and the noise floor.
    """
    if final_intervals not in INTERVALS:
        raise FitError(f"final_intervals must be one of {', '.join(INTERVALS)}, not {final_intervals!r}")
    bounds = {**DEFAULT_BOUNDS, **(bounds or {})}
    base_params = resolve_params(model, names, bounds)
    cands = candidates_for(model, user_effects)
    if not cands:
        raise FitError(
            "no candidate effect to try: the model already has every built-in candidate; "
            "give effects to try with --candidates FILE|FOLDER ... (docs/effects.md)"
        )
    ranges = state_ranges(drops)
    opt = search.get("optimizer") or CMA()
    if isinstance(opt, CMA) and opt.stall is None and stall is not None:
        search = {**search, "optimizer": replace(opt, stall=stall)}
    ident = Identifier(model, base_params, ranges=ranges, **{"ls_evals": 20, **search})  # type: ignore[arg-type]
    seed = ident.seed
    cf = CrossFit(
        model=model,
        drops=drops,
        splits=fold_splits(drops, folds, repeats, seed),
        ranges=ranges,
        base_params=base_params,
        bounds=bounds,
        search=ident,
        refit=ident.with_(cma_evals=refit_evals, sigma=0.25, starts=[{}] if refit_from_centre else None),
    )
    base, control = _base_and_control(cf)
    base_nrmse, base_mse = cf.heldout(control)
    scr = screen(control[0].model, drops, cands, base_params, ranges, bounds, windows(drops, ident.align_s))
    results = [_screened(c, scr[c.name]) for c in sorted(cands, key=lambda c: -scr[c.name].share)]
    for res in results[: len(results) if refits is None else max(0, refits)]:
        _refit_candidate(cf, res, base, control)
    d = Diagnosis(
        base=control,
        results=results,
        base_heldout=base_nrmse,
        base_heldout_mse=base_mse,
        drops=drops,
        test=_test([r for r in results if r.fits], base_mse, alpha, seed),
        floor=noise_floor(control[0].model, drops, ranges, seed=seed),
        folds=folds,
        alpha=alpha,
        seed=seed,
    )
    results.sort(key=lambda r: (not r.fits, -d.gain(r) if r.fits else -r.screening))
    told = d.passed
    if told is not None:
        # only then can an alternative change the verdict: refitted like a candidate, same budget
        for a in _alternatives(model, BASE_ALTERNATIVES if base_alternatives is None else base_alternatives):
            res = CandidateResult(a, math.nan)
            _refit_candidate(cf, res, base, control, guard=True)
            d.alternatives.append(res)
            if d.gain(res) >= MIN_GAIN and d.beats(told, res) > alpha:
                d.on_top[a.name] = _on_top(cf, told, res)
    m = d.missing
    if m is not None:
        d.final = m.final = _final(cf, m, final_intervals, d.floor, control)
    return d


__all__ = ["BUILTIN_CANDIDATES", "PAPER_SEVEN", "Candidate", "Diagnosis", "diagnose", "effect_of"]
