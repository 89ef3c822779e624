"""Which physical effect is missing: screen the candidates cheaply, refit the likely ones,
rank them by held-out error with a penalty per added parameter.

The base model is first identified on its own (from the centre of the bounds). Each candidate
is then added and the whole set re-identified from the base's optimum (optionally also from the
centre of the bounds, where the base fit began), so a candidate can only help the training error;
whether it helps the *validation* drops, by more than its extra parameters buy by themselves,
decides. When none does by at least :data:`MIN_GAIN`, the
verdict is that nothing is missing: the residual is noise or beyond the candidates.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from slopelander.ident.compare import state_ranges
from slopelander.ident.fit import (
    DEFAULT_BOUNDS,
    PAPER_SEVEN,
    FitError,
    FitParam,
    FitResult,
    Problem,
    effect_of,
    fit,
    make_param,
    resolve_params,
    subsets,
)
from slopelander.ident.recording import STATES, Drop
from slopelander.model import Model, UserEffect

BUILTIN_CANDIDATES: dict[str, tuple[str, ...]] = {
    "leg_flex": ("flex_stiffness", "flex_damping"),
    "downhill_torque_growth": ("factor_tau",),
    "downhill_friction_growth": ("factor_mu",),
}
"""Built-in candidate effects and the parameters a refit identifies with them."""
NEUTRAL: dict[str, float] = {"factor_tau": 0.0, "factor_mu": 0.0}
"""Values at which a candidate's parameter leaves the model as it was: the refit starts there,
so it begins at the base model's optimum."""
PENALTY = 0.02
"""Relative validation-error penalty per added parameter."""
MIN_GAIN = 0.05
"""A candidate must cut the (penalised) validation NRMSE by this fraction to count as missing."""


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
    """Fraction of the base residual one step along the candidate's direction removes."""
    fits: list[FitResult] = field(default_factory=list)

    @property
    def validation_nrmse(self) -> float:
        return float(np.mean([f.validation_nrmse for f in self.fits]))

    @property
    def train_nrmse(self) -> float:
        return float(np.mean([f.train_nrmse for f in self.fits]))

    @property
    def score(self) -> float:
        return self.validation_nrmse * (1.0 + PENALTY * len(self.candidate.params))

    def values(self) -> dict[str, float]:
        return {p: float(np.mean([f.values[p] for f in self.fits])) for p in self.candidate.params}


@dataclass
class Diagnosis:
    base: list[FitResult]
    results: list[CandidateResult]
    """Refitted candidates, best first; then screened-out ones (no fits)."""

    @property
    def base_validation(self) -> float:
        return float(np.mean([f.validation_nrmse for f in self.base]))

    @property
    def base_train(self) -> float:
        return float(np.mean([f.train_nrmse for f in self.base]))

    def gain(self, r: CandidateResult) -> float:
        """Relative fall of the penalised validation NRMSE from the base model's."""
        return 1.0 - r.score / self.base_validation

    @property
    def missing(self) -> CandidateResult | None:
        fitted = [r for r in self.results if r.fits]
        if fitted and self.gain(fitted[0]) >= MIN_GAIN:
            return fitted[0]
        return None

    def verdict(self) -> str:
        m = self.missing
        if m is not None:
            vals = ", ".join(f"{k} = {v:.4g}" for k, v in m.values().items())
            return (
                f"missing: {m.candidate.name} (validation NRMSE {self.base_validation:.4f} -> "
                f"{m.validation_nrmse:.4f}, {100 * self.gain(m):.0f} % better after the penalty; {vals})"
            )
        fitted = [r for r in self.results if r.fits]
        best = (
            f" (best candidate {fitted[0].candidate.name}: {100 * self.gain(fitted[0]):+.1f} %)"
            if fitted
            else ""
        )
        return (
            "nothing missing: no candidate explains the residual better than noise"
            f"{best}; the {len(self.results)} candidates were tried"
        )

    def table(self) -> str:
        lines = [
            "| rank | candidate | screening | train NRMSE | validation NRMSE | gain | fitted |",
            "|---:|---|---:|---:|---:|---:|---|",
            f"| - | (base) | - | {self.base_train:.4f} | {self.base_validation:.4f} | - | - |",
        ]
        for i, r in enumerate(self.results, 1):
            if r.fits:
                vals = ", ".join(f"{k} {v:.4g}" for k, v in r.values().items())
                lines.append(
                    f"| {i} | {r.candidate.name} | {100 * r.screening:.0f} % | {r.train_nrmse:.4f} "
                    f"| {r.validation_nrmse:.4f} | {100 * self.gain(r):+.1f} % | {vals} |"
                )
            else:
                lines.append(f"| {i} | {r.candidate.name} | {100 * r.screening:.0f} % | not refitted | | | |")
        return "\n".join(lines)


def neutral_values(cand: Candidate) -> dict[str, float]:
    """Values at which the candidate leaves the model as it was: the built-ins' known ones, a
    user effect's declared ``neutral`` values."""
    out = {n: NEUTRAL[n] for n in cand.params if n in NEUTRAL}
    if cand.user is not None:
        out.update({n: p.neutral for n, p in cand.user.parameters.items() if p.neutral is not None})
    return out


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


def screen(
    base_model: Model,
    drops: list[Drop],
    cands: list[Candidate],
    base_params: list[FitParam],
    ranges: np.ndarray,
    bounds: dict[str, tuple[float, float]],
) -> dict[str, float]:
    """Cheap signature test: switch each candidate on (a tenth of its range from "off", or at
    the centre of its bounds) and measure
    how much of the base residual the change in the simulated states removes (best step along
    it). One simulation per candidate and drop."""
    base_prob = Problem(base_model, drops, [], ranges)
    r = base_prob.residuals([])
    out = {}
    for c in cands:
        params = candidate_params(base_model, c, [], bounds)
        prob = Problem(c.add_to(base_model), drops, params, ranges)
        # a small step from "off" where the effect has an off value, else the bounds' centre
        off = neutral_values(c)
        u = [min(1.0, p.unit(off[p.name]) + 0.1) if p.name in off else 0.5 for p in params]
        d = prob.residuals(u) - r
        dd = float(d @ d)
        alpha = -float(r @ d) / dd if dd > 0 else 0.0
        alpha = min(max(alpha, 0.0), 1.0)
        rest = r + alpha * d
        out[c.name] = max(0.0, 1.0 - float(rest @ rest) / float(r @ r))
    return out


def residual_signature(prob: Problem, u: np.ndarray) -> dict[str, float]:
    """Share of the squared residual per state: which states the base model gets wrong."""
    r = prob.residuals(u).reshape(-1, len(STATES))
    e = (r**2).sum(axis=0)
    return dict(zip(STATES, (e / max(e.sum(), 1e-300)).tolist(), strict=True))


def diagnose(
    model: Model,
    drops: list[Drop],
    *,
    user_effects: list[UserEffect] | None = None,
    names: list[str] | None = None,
    bounds: dict[str, tuple[float, float]] | None = None,
    repeats: int = 1,
    refits: int | None = None,
    seed: int = 0,
    cma_evals: int = 400,
    refit_evals: int = 200,
    ls_evals: int = 20,
    refit_from_centre: bool = False,
    workers: int | None = None,
    client=None,
    progress=None,
) -> Diagnosis:
    """Find the effect ``model`` is missing to explain ``drops``.

    ``names``: the base model's fitted parameters (default the paper's seven it has);
    ``repeats``: training/validation splits (60/40); ``refits``: how many of the screened
    candidates get the expensive refit (default all); ``refit_from_centre``: each refit's
    CMA-ES budget is shared between a run from the base optimum and one from the centre of the
    bounds, where the base fit began (the base optimum can sit far from the answer when the
    base model bent its parameters to mimic the missing effect).
    """
    bounds = {**DEFAULT_BOUNDS, **(bounds or {})}
    base_params = resolve_params(model, names, bounds)
    cands = candidates_for(model, user_effects)
    if not cands:
        raise FitError("no candidate effect to try: the model already has every built-in candidate")
    ranges = state_ranges(drops)
    splits = subsets(len(drops), repeats, seed=seed)
    kw = {"ranges": ranges, "workers": workers, "client": client, "progress": progress, "ls_evals": ls_evals}
    base_fits = []
    for k, (tr, va) in enumerate(splits):
        train = [drops[i] for i in tr]
        base_fits.append(
            fit(
                model,
                train,
                base_params,
                seed=seed + k,
                cma_evals=cma_evals,
                validation=[drops[i] for i in va],
                **kw,
            )
        )
    first_train = [drops[i] for i in splits[0][0]]
    scores = screen(base_fits[0].model, first_train, cands, base_params, ranges, bounds)
    order = sorted(cands, key=lambda c: -scores[c.name])
    n_refit = len(order) if refits is None else max(0, refits)
    results = []
    for i, c in enumerate(order):
        res = CandidateResult(c, scores[c.name])
        if i < n_refit:
            params = candidate_params(model, c, base_params, bounds)
            for k, (tr, va) in enumerate(splits):
                res.fits.append(
                    fit(
                        c.add_to(model),
                        [drops[j] for j in tr],
                        params,
                        seed=seed + k,
                        cma_evals=refit_evals,
                        validation=[drops[j] for j in va],
                        start=base_fits[k].values,
                        also=[neutral_values(c)],
                        sigma=0.25,
                        starts=[{}] if refit_from_centre else None,
                        **kw,
                    )
                )
        results.append(res)
    results.sort(key=lambda r: (not r.fits, r.score if r.fits else -r.screening))
    return Diagnosis(base_fits, results)


__all__ = ["BUILTIN_CANDIDATES", "PAPER_SEVEN", "Candidate", "Diagnosis", "diagnose", "effect_of"]
