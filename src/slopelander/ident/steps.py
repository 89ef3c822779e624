"""Add effects one at a time and watch the error fall: base -> + effect -> + effect ...

Each step re-identifies the parameters (the previous step's values plus the new effect's),
on the same training subsets, and reports training and validation NRMSE overall and per state.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slopelander.ident.compare import compare, state_ranges
from slopelander.ident.diagnose import NEUTRAL, Candidate, candidate_params
from slopelander.ident.fit import DEFAULT_BOUNDS, FitResult, Identifier, resolve_params, subsets, windows
from slopelander.ident.optimizers import Optimizer
from slopelander.ident.recording import STATES, Drop
from slopelander.model import Model


@dataclass
class Step:
    label: str
    fits: list[FitResult]
    validation_per_state: np.ndarray
    validation_per_drop: np.ndarray | None = None
    """Held-out NRMSE of each validation drop (over the splits), for the spread."""

    @property
    def spread(self) -> float:
        """Standard error of the validation NRMSE over the validation drops."""
        v = self.validation_per_drop
        return float(np.std(v, ddof=1) / np.sqrt(len(v))) if v is not None and len(v) > 1 else float("nan")

    @property
    def train(self) -> float:
        return float(np.mean([f.train_nrmse for f in self.fits]))

    @property
    def validation(self) -> float:
        return float(np.mean([f.validation_nrmse for f in self.fits]))


@dataclass
class Steps:
    steps: list[Step]

    def table(self) -> str:
        """Error per step, with the spread over the validation drops: the validation NRMSE's
        standard error, and the fall from the previous step paired drop by drop (mean +- its
        standard error; a fall within about twice its error is not shown by these drops)."""
        head = (
            "| step | train NRMSE | validation NRMSE (+- s.e. over drops) | fall (paired) | "
            + " | ".join(f"val {s}" for s in STATES)
            + " |"
        )
        lines = [head, "|---|" + "---:|" * (3 + len(STATES))]
        prev = None
        for s in self.steps:
            fall = "-"
            if (
                prev is not None
                and prev.validation_per_drop is not None
                and s.validation_per_drop is not None
            ):
                d = prev.validation_per_drop - s.validation_per_drop
                se = np.std(d, ddof=1) / np.sqrt(len(d)) if len(d) > 1 else float("nan")
                fall = f"{d.mean():+.4f} +- {se:.4f}"
            lines.append(
                f"| {s.label} | {s.train:.4f} | {s.validation:.4f} +- {s.spread:.4f} | {fall} | "
                + " | ".join(f"{v:.4f}" for v in s.validation_per_state)
                + " |"
            )
            prev = s
        return "\n".join(lines)

    def plot(self, path: str | Path) -> Path:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        x = np.arange(len(self.steps))
        fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
        a.plot(x, [s.train for s in self.steps], "o-", label="training")
        a.errorbar(
            x,
            [s.validation for s in self.steps],
            yerr=[s.spread for s in self.steps],
            fmt="s-",
            capsize=4,
            label="validation (+- s.e. over drops)",
        )
        a.set_ylabel("NRMSE (angular x2)")
        a.set_title("error per step")
        a.legend()
        per = np.array([s.validation_per_state for s in self.steps])
        for i, name in enumerate(STATES):
            b.plot(x, per[:, i], "o-", label=name)
        b.set_title("validation NRMSE per state")
        b.legend(fontsize=8)
        for ax in (a, b):
            ax.set_xticks(x, [s.label for s in self.steps], rotation=20, ha="right", fontsize=8)
            ax.set_ylim(bottom=0)
            ax.grid(alpha=0.3)
        fig.tight_layout()
        path = Path(path)
        fig.savefig(path, dpi=90)
        plt.close(fig)
        return path


def run_steps(
    model: Model,
    drops: list[Drop],
    effects: list[Candidate],
    *,
    names: list[str] | None = None,
    bounds: dict[str, tuple[float, float]] | None = None,
    repeats: int = 1,
    seed: int = 0,
    cma_evals: int = 400,
    refit_evals: int = 200,
    ls_evals: int = 20,
    workers: int | None = None,
    client=None,
    progress=None,
    optimizer: Optimizer | None = None,
    align_s: float | None = None,
) -> Steps:
    """Fit ``model``, then ``model`` + effects[0], + effects[1], ... re-identifying at each step
    (``align_s``: each drop's clock window, :func:`~slopelander.ident.clocks.align_windows`)."""
    bounds = {**DEFAULT_BOUNDS, **(bounds or {})}
    ranges = state_ranges(drops)
    splits = subsets(len(drops), repeats, seed=seed)
    params = resolve_params(model, names, bounds)
    ident = Identifier(
        model,
        params,
        ranges=ranges,
        workers=workers,
        client=client,
        progress=progress,
        ls_evals=ls_evals,
        optimizer=optimizer,
        align_s=align_s,
    )
    out: list[Step] = []
    prev: list[FitResult] = []
    current = model
    for i in range(len(effects) + 1):
        if i:
            c = effects[i - 1]
            params = candidate_params(current, c, params, bounds)
            current = c.add_to(current)
        step = ident.with_(
            model=current,
            params=params,
            cma_evals=refit_evals if prev else cma_evals,
            also=[NEUTRAL] if prev else None,
            sigma=0.2 if prev else 0.3,
        )
        fits = []
        for k, (tr, va) in enumerate(splits):
            one = step.with_(seed=seed + k, start=prev[k].values if prev else None)
            fits.append(one.fit([drops[j] for j in tr], [drops[j] for j in va]).result_)
        comps = [
            compare(f.model, [drops[j] for j in va], ranges, windows([drops[j] for j in va], step.align_s))
            for f, (_, va) in zip(fits, splits, strict=True)
        ]
        per_state = np.mean([c.per_state for c in comps], axis=0)
        per_drop = np.array([d.nrmse for c in comps for d in c.drops])
        label = "base" if i == 0 else f"+ {effects[i - 1].name}"
        out.append(Step(label, fits, per_state, per_drop))
        prev = fits
    return Steps(out)
