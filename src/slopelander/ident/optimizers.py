"""The global search of a fit, as an object a user can swap (``Identifier(optimizer=...)``).

A fit searches the unit cube of its parameters (each parameter's bounds mapped to 0..1, log
scale where they span more than a decade) for the lowest sum of squared residuals, then polishes
the best point with least squares. The global part is pluggable, as scikit-learn's and PySINDy's
estimators take their optimizer: anything with a ``name`` and a ``search(task)`` method that
asks ``task.costs`` for batches of points. The task keeps the best point ever evaluated, so an
optimizer need not; a batch is evaluated in parallel (one point's drops shared between the
processes), so an optimizer that asks for many points at once uses every core.

:class:`CMA` (CMA-ES, the default) and :class:`DifferentialEvolution` (``scipy.optimize``) are
the two shipped; ``OPTIMIZERS`` names them for the command line's ``--optimizer``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass
class SearchTask:
    """What a global search is given: a batch cost function on the unit cube, where its runs
    start, its budget of evaluations, its seed and its first step (in units of the bounds)."""

    evaluate: Callable[[list[np.ndarray]], list[float]]
    """Costs of a batch of points (evaluated in parallel)."""
    origins: list[np.ndarray]
    """Where runs start: the fit's start first, then any further starts and random restarts."""
    budget: int
    seed: int
    sigma: float
    best_u: np.ndarray
    best_cost: float
    progress: Callable[[int], None] = field(default=lambda n: None)

    @property
    def dim(self) -> int:
        return len(self.best_u)

    def costs(self, points: Sequence[np.ndarray]) -> list[float]:
        """Evaluate ``points``; the lowest cost seen so far and its point are kept."""
        X = [np.asarray(x, dtype=float) for x in points]
        costs = self.evaluate(X)
        self.progress(len(X))
        i = int(np.argmin(costs))
        if costs[i] < self.best_cost:
            self.best_u, self.best_cost = X[i].copy(), costs[i]
        return costs


@runtime_checkable
class Optimizer(Protocol):
    """A global search over the unit cube: evaluates points through ``task.costs`` within
    ``task.budget`` evaluations (the task keeps the best)."""

    name: str

    def search(self, task: SearchTask) -> None: ...


@dataclass(frozen=True)
class CMA:
    """CMA-ES (the ``cma`` package), one run from each origin sharing the budget; with one
    parameter (CMA-ES needs two dimensions) a scan of the line instead.

    ``popsize``: points per generation (default 4 + 3 ln n, at least 8, made even so that a
    seed searches alike on any number of processes); ``tolfun``: stop when the generation's
    costs differ by less. ``stall``: stop a run once that many generations in a row have not
    lowered the best cost seen by more than ``stall_rtol`` of it (None: run to the budget). A
    search that starts at an optimum (a refit from the base model's, a candidate that explains
    nothing) then ends after a few generations instead of spending its budget to confirm it,
    while one that keeps finding lower costs runs on."""

    popsize: int | None = None
    tolfun: float = 1e-10
    stall: int | None = None
    stall_rtol: float = 1e-6
    name: str = "cma"

    def population(self, dim: int) -> int:
        if self.popsize is not None:
            return self.popsize
        size = max(8, 4 + int(3 * math.log(dim)))
        return size + size % 2

    def search(self, task: SearchTask) -> None:
        if task.budget <= 0:
            return
        if task.dim == 1:
            task.costs([np.array([x]) for x in np.linspace(0.0, 1.0, max(3, min(task.budget, 41)))])
            return
        import cma

        runs = len(task.origins)
        for run, origin in enumerate(task.origins):
            es = cma.CMAEvolutionStrategy(
                list(origin),
                task.sigma,
                {
                    "bounds": [0, 1],
                    "popsize": self.population(task.dim),
                    "seed": task.seed + 1 + 100 * run,
                    "verbose": -9,
                    "maxfevals": task.budget // runs,
                    "tolfun": self.tolfun,
                },
            )
            still, best = 0, task.best_cost
            while not es.stop():
                X = es.ask()
                es.tell(X, task.costs(X))
                if self.stall is None:
                    continue
                still = still + 1 if task.best_cost >= best * (1.0 - self.stall_rtol) else 0
                best = min(best, task.best_cost)
                if still >= self.stall:
                    break


@dataclass(frozen=True)
class DifferentialEvolution:
    """Differential evolution (``scipy.optimize.differential_evolution``), one run from each
    origin sharing the budget: the origin is one member of a Latin-hypercube population over the
    whole cube, and each generation is evaluated as one batch. Slower to converge than CMA-ES
    near a good start, but makes no assumption of a smooth, unimodal basin.

    ``popsize``: members per parameter (scipy's multiplier), ``mutation`` and ``recombination``
    as scipy's."""

    popsize: int = 5
    mutation: tuple[float, float] = (0.5, 1.0)
    recombination: float = 0.7
    name: str = "de"

    def search(self, task: SearchTask) -> None:
        from scipy.optimize import differential_evolution

        members = self.popsize * task.dim
        per_run = task.budget // max(1, len(task.origins))
        generations = per_run // members - 1  # the first generation is the initial population
        if generations < 1:
            return

        def batch(x: np.ndarray) -> np.ndarray:  # scipy's vectorized form: x is (dim, S)
            return np.asarray(task.costs(list(np.atleast_2d(x).T)))

        for run, origin in enumerate(task.origins):
            differential_evolution(
                batch,
                [(0.0, 1.0)] * task.dim,
                x0=np.asarray(origin, dtype=float),
                popsize=self.popsize,
                maxiter=generations,
                mutation=self.mutation,
                recombination=self.recombination,
                seed=task.seed + 1 + 100 * run,
                polish=False,
                tol=0.0,
                vectorized=True,
                updating="deferred",
            )


OPTIMIZERS: dict[str, type] = {"cma": CMA, "de": DifferentialEvolution}
"""The shipped global searches by the name ``--optimizer`` takes."""


def optimizer_named(name: str) -> Optimizer:
    """The shipped optimizer called ``name``, with its default settings."""
    try:
        return OPTIMIZERS[name]()
    except KeyError:
        raise ValueError(f"unknown optimizer {name!r}: choose one of {', '.join(OPTIMIZERS)}") from None
