"""Identify named model parameters from recorded drops, as the paper did (Sec. IV-D).

A global search (CMA-ES, from the given model's values, or from the centre of the bounds when
asked) then a local least-squares polish with a finite-difference Jacobian whose columns are
simulated in parallel. The Jacobian at the optimum also gives confidence intervals and shows
directions the data cannot pin down (flat or correlated), which are reported as warnings.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from slopelander.errors import SlopelanderError
from slopelander.ident.compare import WEIGHTS, compare, predict, state_ranges
from slopelander.ident.recording import Drop
from slopelander.model import BUILTIN_EFFECTS, Model

PAPER_SEVEN: tuple[str, ...] = (
    "flex_stiffness",
    "flex_damping",
    "factor_tau",
    "factor_mu",
    "ground_stiffness",
    "ground_damping",
    "friction_kinetic",
)
"""The parameters the paper identified from its drops (Table II, GA means): k_q, b_q,
factor_tau, factor_mu_k, k_g, b_g, mu_k. Masses and inertias were measured, not fitted."""

DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {
    "flex_stiffness": (2.0, 200.0),
    "flex_damping": (0.005, 1.0),
    "factor_tau": (0.0, 0.01),
    "factor_mu": (0.0, 3.0),
    "ground_stiffness": (2e3, 2e5),
    "ground_damping": (50.0, 3000.0),
    "friction_kinetic": (0.2, 1.2),
    "eot_stiffness": (10.0, 2000.0),
    "eot_damping": (0.05, 10.0),
}
"""Search bounds of the parameters a user is likely to fit; wide, a decade or more either side
of the paper's values where the quantity is a stiffness or damping."""


class FitError(SlopelanderError, ValueError):
    """A parameter that cannot be fitted as asked (unknown, no bounds, its effect is off)."""


@dataclass(frozen=True)
class FitParam:
    name: str
    low: float
    high: float
    log: bool
    """Searched on a log scale (bounds positive and more than a decade apart)."""

    def value(self, u: float) -> float:
        u = min(max(u, 0.0), 1.0)
        if self.log:
            return self.low * (self.high / self.low) ** u
        return self.low + (self.high - self.low) * u

    def unit(self, value: float) -> float:
        value = min(max(float(value), self.low), self.high)
        if self.log:
            return math.log(value / self.low) / math.log(self.high / self.low)
        return (value - self.low) / (self.high - self.low)

    def slope(self, u: float) -> float:
        """d value / d u, to carry uncertainties from the unit cube to the parameter."""
        return self.value(u) * math.log(self.high / self.low) if self.log else self.high - self.low


def make_param(name: str, low: float, high: float) -> FitParam:
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise FitError(f"parameter {name!r}: bounds {low}..{high} must be finite with low < high")
    return FitParam(name, float(low), float(high), low > 0 and high / low > 10.0)


def effect_of(name: str) -> str | None:
    for e in BUILTIN_EFFECTS.values():
        if name in e.parameters:
            return e.name
    return None


def resolve_params(
    model: Model, names: Sequence[str] | None = None, bounds: dict[str, tuple[float, float]] | None = None
) -> list[FitParam]:
    """The fit parameters: ``names`` (default the paper's seven, less those whose effect the
    model lacks) with ``bounds`` overriding :data:`DEFAULT_BOUNDS` and a user effect's
    declared bounds."""
    bounds = {**DEFAULT_BOUNDS, **declared_bounds(model), **(bounds or {})}
    explicit = names is not None
    names = list(PAPER_SEVEN if names is None else names)
    user = {p: e for e in model.user_effects for p in e.parameters}
    out = []
    for n in names:
        eff = effect_of(n)
        if n in user:
            pass
        elif n not in model.params.values:
            raise FitError(f"unknown parameter {n!r}")
        elif eff is not None and eff not in model.effects:
            if explicit:
                raise FitError(f"parameter {n!r} belongs to effect {eff!r}, which the model does not have")
            continue
        if n not in bounds:
            raise FitError(f"parameter {n!r} has no default bounds: give them as {n}=LOW:HIGH")
        out.append(make_param(n, *bounds[n]))
    if not out:
        raise FitError("nothing to fit")
    return out


def declared_bounds(model: Model) -> dict[str, tuple[float, float]]:
    """The bounds the model's user effects declare for their parameters (finite ones only)."""
    return {n: (p.low, p.high) for n, p in model.user_parameters().items() if p.bounded}


def apply(model: Model, params: Sequence[FitParam], values: Sequence[float]) -> Model:
    """``model`` with the named parameters set (built-in or of a user effect)."""
    changes = {p.name: float(v) for p, v in zip(params, values, strict=True)}
    return model.with_params(**changes) if changes else model


@dataclass
class Problem:
    """Residuals of a model over a set of drops as a function of the unit-cube parameters."""

    model: Model
    drops: list[Drop]
    params: list[FitParam]
    ranges: np.ndarray

    def __post_init__(self) -> None:
        horizon = max(float(d.t[-1]) for d in self.drops) + 0.01
        self.model = replace(self.model, criteria=replace(self.model.criteria, horizon=horizon))
        # the samples after contact, and what was measured there: the same at every evaluation;
        # a gap in a recording (NaN) is no residual at all, and each state's mean is over its own
        # samples (as compare's NRMSE)
        self._after = [d.t >= 0 for d in self.drops]
        self._measured = [d.states[a] for d, a in zip(self.drops, self._after, strict=True)]
        self._seen = [np.isfinite(m) for m in self._measured]
        self._gaps = any(not s.all() for s in self._seen)
        self._scale = [
            np.sqrt(WEIGHTS / WEIGHTS.sum())
            / self.ranges
            / np.sqrt(np.maximum(s.sum(axis=0), 1) * len(self.drops))
            for s in self._seen
        ]

    def values(self, u: Sequence[float]) -> list[float]:
        return [p.value(float(x)) for p, x in zip(self.params, u, strict=True)]

    def model_at(self, u: Sequence[float]) -> Model:
        return apply(self.model, self.params, self.values(u))

    def residuals(self, u: Sequence[float], which: Sequence[int] | None = None) -> np.ndarray:
        """The residual vector at ``u``; ``which``: only these drops' parts, in this order (a
        single point's evaluation shared between processes)."""
        idx = range(len(self.drops)) if which is None else which
        try:
            m = self.model_at(u)
        except SlopelanderError:
            return np.full(sum(int(self._seen[i].sum()) for i in idx), 10.0)
        out = [np.zeros(0)]
        for i in idx:
            sim, _ = predict(m, self.drops[i], outcome=False)
            r = (sim[self._after[i]] - self._measured[i]) * self._scale[i]
            out.append(r[self._seen[i]] if self._gaps else r.ravel())
        r = np.concatenate(out)
        return np.where(np.isfinite(r), r, 10.0)

    def groups(self) -> np.ndarray:
        """The drop each residual belongs to (for intervals over drops)."""
        return np.concatenate([np.full(int(s.sum()), i) for i, s in enumerate(self._seen)])

    @property
    def size(self) -> int:
        return sum(int(s.sum()) for s in self._seen)

    def cost(self, u: Sequence[float]) -> float:
        r = self.residuals(u)
        return float(r @ r)


# -- running many evaluations ---------------------------------------------------------------
_WORKER_PROBLEM: Problem | None = None


def _init_worker(problem: Problem) -> None:
    global _WORKER_PROBLEM
    _WORKER_PROBLEM = problem


def _worker_part(task: tuple[np.ndarray, list[int]]) -> np.ndarray:
    assert _WORKER_PROBLEM is not None
    return _WORKER_PROBLEM.residuals(task[0], task[1])


def _dask_keep(problem: Problem, expected: str) -> Problem:
    """The fit's drops and model, held on the cluster once per fit (run again from its task
    should every copy be lost with its worker)."""
    from slopelander.envelope.cluster import check_worker

    check_worker(expected)
    return problem


def _dask_part(
    problem: Problem, points: list[np.ndarray], which: list[int] | None, expected: str
) -> list[np.ndarray]:
    from slopelander.envelope.cluster import check_worker

    check_worker(expected)
    return [problem.residuals(u, which) for u in points]


WORKERS_ENV = "SLOPELANDER_WORKERS"


def default_workers() -> int:
    """Processes for the evaluations: ``SLOPELANDER_WORKERS`` if set (a machine shared with other
    work, a test runner's worker), else one per core."""
    raw = os.environ.get(WORKERS_ENV, "").strip()
    if not raw:
        return os.cpu_count() or 1
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if n < 1:
        raise FitError(f"{WORKERS_ENV}={raw!r}: give a whole number of processes, 1 or more")
    return n


class Evaluator:
    """Evaluates residual vectors for many parameter points: in this process, on a pool of
    forked processes (one per core), or on a Dask cluster."""

    def __init__(self, problem: Problem, workers: int | None = None, client=None) -> None:
        self.problem = problem
        self.client = client
        self.workers = workers if workers is not None else default_workers()
        self._pool = None
        # the user effects' laws compiled here, once, before the workers fork (they inherit them)
        problem.model.kernel()
        if client is None and self.workers > 1 and "fork" in mp.get_all_start_methods():
            self._pool = mp.get_context("fork").Pool(self.workers, _init_worker, (problem,))
        self._held = None
        if client is not None:
            from slopelander.envelope.cluster import fingerprint, prepare

            prepare(client, ("landing",))
            self._expected = fingerprint()
            # sent once: each task then carries a point and the drops it simulates, not the drops
            self._held = client.submit(_dask_keep, problem, self._expected, pure=False)
        self.nfev = 0

    def residuals(self, points: Sequence[np.ndarray]) -> list[np.ndarray]:
        self.nfev += len(points)
        if self.client is not None:
            return self._on_cluster(points)
        if self._pool is not None:
            # each point's drops shared out between the processes, one part a task: a single
            # point (a least-squares step) uses them all, and a population's slow points (long
            # slides) do not leave a process idle; the parts join into the same vector in the
            # same order
            n = len(self.problem.drops)
            chunks = [c.tolist() for c in np.array_split(np.arange(n), min(self.workers, n))]
            parts = self._pool.map(_worker_part, [(u, c) for u in points for c in chunks], chunksize=1)
            k = len(chunks)
            return [np.concatenate(parts[i * k : (i + 1) * k]) for i in range(len(points))]
        return [self.problem.residuals(u) for u in points]

    def _on_cluster(self, points: Sequence[np.ndarray]) -> list[np.ndarray]:
        """As the pool, on the cluster's worker threads, one task a thread: a block of points,
        or, with fewer points than threads (a least-squares step), a part of each point's
        drops, joined in the same order. A point takes milliseconds to tenths of a second, a
        task's round trip milliseconds: one task per point would spend as long on the trips.
        Each task is asked of one thread's worker (another takes it if that one is gone): left
        to itself, the scheduler keeps them all where the drops are held."""
        from slopelander.envelope.cluster import gather, slots

        where = slots(self.client)
        k = max(1, len(where))
        n, m = len(self.problem.drops), len(points)
        if m >= k:
            tasks = [([points[i] for i in b], None) for b in np.array_split(np.arange(m), k)]
            parts = 1
        else:
            parts = min(n, -(-k // max(1, m)))
            chunks = [c.tolist() for c in np.array_split(np.arange(n), parts)]
            tasks = [([u], c) for u in points for c in chunks]
        placed = [
            {"workers": [where[i % k]], "allow_other_workers": True} if where else {}
            for i in range(len(tasks))
        ]
        futures = [
            self.client.submit(_dask_part, self._held, us, which, self._expected, pure=False, **place)
            for (us, which), place in zip(tasks, placed, strict=True)
        ]
        got: list = [None] * len(futures)
        gather(futures, got.__setitem__)
        if parts == 1:
            return [r for block in got for r in block]
        return [np.concatenate([got[i * parts + j][0] for j in range(parts)]) for i in range(m)]

    def close(self) -> None:
        if self._held is not None:
            self._held.release()
            self._held = None
        if self._pool is not None:
            self._pool.terminate()
            self._pool.join()
            self._pool = None

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# -- the fit ---------------------------------------------------------------------------------
@dataclass
class FitResult:
    params: list[FitParam]
    values: dict[str, float]
    u: np.ndarray
    cost: float
    train_nrmse: float
    ci95: dict[str, float]
    """Half-width of the 95 % confidence interval: the sandwich over drops (each drop one
    independent unit), Student's t with drops - 1 degrees of freedom."""
    warnings: list[str]
    nfev: int
    seconds: float
    model: Model
    validation_nrmse: float | None = None
    train_names: list[str] = field(default_factory=list)
    validation_names: list[str] = field(default_factory=list)
    start_values: dict[str, float] = field(default_factory=dict)
    """Where the search began (the given model's values unless asked otherwise)."""
    start_cost: float = math.nan
    start_nrmse: float = math.nan
    """Training NRMSE at the start: a fit never ends worse in cost, and says so if its NRMSE is."""
    ranges: np.ndarray | None = None
    """The states' normalising ranges the NRMSEs were taken with."""


def _jacobian(ev: Evaluator, u: np.ndarray, r0: np.ndarray, h: float = 1e-3) -> np.ndarray:
    pts = []
    steps = []
    for i in range(len(u)):
        step = h if u[i] + h <= 1.0 else -h
        v = u.copy()
        v[i] += step
        pts.append(v)
        steps.append(step)
    cols = ev.residuals(pts)
    return np.column_stack([(c - r0) / s for c, s in zip(cols, steps, strict=True)])


def identifiability(
    params: list[FitParam],
    J: np.ndarray,
    u: np.ndarray,
    r: np.ndarray,
    values: dict[str, float],
    groups: np.ndarray | None = None,
) -> tuple[dict[str, float], list[str]]:
    """95 % half-widths and warnings for parameters the data cannot identify: a flat direction
    (tiny singular value), a strong correlation, or an interval wider than half the value.

    With ``groups`` (the drop of each residual), the covariance is the sandwich over drops:
    the drops are the independent units, the samples inside one are not (rates are slopes over
    several samples, a model error is one smooth curve), so each drop's summed score J_i^T r_i
    is one observation; the half-width uses Student's t with (drops - 1) degrees of freedom.
    Without, the Gauss-Newton covariance treats every sample as independent (optimistic)."""
    n = len(params)
    dof = max(len(r) - n, 1)
    s2 = float(r @ r) / dof
    JtJ = J.T @ J
    quantile = 1.96
    warnings = []
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    if sv.size and sv[0] > 0:
        for k in np.flatnonzero(sv / sv[0] < 1e-3):
            lead = [params[i].name for i in np.argsort(-np.abs(Vt[k]))[:2]]
            warnings.append(
                f"flat direction: the data barely constrain a combination of "
                f"{' and '.join(lead)} (singular value ratio {sv[k] / sv[0]:.1e})"
            )
    cov = np.linalg.pinv(JtJ) * s2
    if groups is not None:
        from scipy.stats import t as student

        ids = np.unique(groups)
        if len(ids) > 1:
            scores = np.array([J[groups == g].T @ r[groups == g] for g in ids])
            inv = np.linalg.pinv(JtJ)
            cov = inv @ (scores.T @ scores) @ inv * len(ids) / (len(ids) - 1)
            quantile = float(student.ppf(0.975, len(ids) - 1))
    sd_u = np.sqrt(np.clip(np.diag(cov), 0, None))
    # a parameter that loads on a flat direction is not known: the pseudo-inverse drops that
    # direction and would read it as perfectly known (+-0)
    unknown = np.zeros(n, dtype=bool)
    flat = sv <= (sv[0] * 1e-3 if sv.size and sv[0] > 0 else np.inf)
    for kk in np.flatnonzero(flat):
        unknown |= np.abs(Vt[kk]) > 0.1
    ci = {}
    for i, p in enumerate(params):
        ci[p.name] = math.inf if unknown[i] else quantile * sd_u[i] * p.slope(float(u[i]))
        v = values[p.name]
        if unknown[i]:
            warnings.append(
                f"{p.name} is not identified: the drops do not change with it near {v:.3g} "
                "(no interval can be given)"
            )
        elif ci[p.name] > 0.5 * abs(v) and abs(v) > 0:
            warnings.append(
                f"{p.name} is poorly identified: 95 % interval +-{ci[p.name]:.3g} on a value of {v:.3g}"
            )
        if u[i] < 0.01 or u[i] > 0.99:
            warnings.append(
                f"{p.name} = {v:.3g} sits at its bound ({p.low:g}..{p.high:g}): widen the bounds "
                "or the data do not need it"
            )
    d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(d, d)
    for i in range(n):
        for j in range(i + 1, n):
            if abs(corr[i, j]) > 0.95 and not (unknown[i] or unknown[j]):
                warnings.append(
                    f"{params[i].name} and {params[j].name} are correlated "
                    f"(rho = {corr[i, j]:+.2f}): the data fix their combination, not each"
                )
    return ci, warnings


@dataclass
class Identifier:
    """Identification as an estimator, in the scikit-learn / PySINDy habit: the configuration
    is given once, :meth:`fit` learns the named parameters from drops, :meth:`predict`
    simulates drops with the fitted model and :meth:`score` says how well it matches them.

    ``params``: what to identify (names or :class:`FitParam`; default the paper's seven the
    model has), ``bounds`` override the default search bounds. ``cma_evals`` bounds the global
    search (CMA-ES), ``ls_evals`` the least-squares polish. The search starts from the model's
    own values (clipped into the bounds), or from the centre of the bounds with
    ``from_centre``, with ``start`` (values by name, e.g. a previous fit's) overriding either;
    the start is evaluated first and kept if nothing beats it, so a fit never ends worse in cost
    than where it began. ``sigma`` is the initial search width in units of the bounds. Points
    in ``also`` (values by name; unnamed ones from ``start``) are evaluated first and kept if
    best. ``restarts`` splits the global budget over that many more CMA-ES runs from random
    points (a noisy cost has false basins one run can fall into); ``starts`` adds one run from
    each of these points (unnamed values at the centre of the bounds). ``ranges`` fixes the
    states' normalising ranges (default: those of the drops fitted and validated on).
    ``progress`` is called with the number of new model evaluations (a progress bar).

    After :meth:`fit`: ``result_`` (the :class:`FitResult`: values, intervals, warnings),
    ``model_`` (the fitted model) and ``values_``.
    """

    model: Model
    params: Sequence[str | FitParam] | None = None
    bounds: dict[str, tuple[float, float]] | None = None
    cma_evals: int = 400
    ls_evals: int = 30
    seed: int = 0
    sigma: float = 0.3
    from_centre: bool = False
    start: dict[str, float] | None = None
    also: list[dict[str, float]] | None = None
    restarts: int = 0
    starts: list[dict[str, float]] | None = None
    ranges: np.ndarray | None = None
    workers: int | None = None
    client: object = None
    progress: Callable[[int], None] | None = None
    result_: FitResult | None = field(default=None, init=False, repr=False)

    def with_(self, **changes: object) -> Identifier:
        """A copy with some settings changed (unfitted): one per fold of a cross-fit."""
        return replace(self, **changes)

    def fit_params(self) -> list[FitParam]:
        """The parameters this identifier fits, resolved against its model."""
        ps = self.params
        if ps is not None and all(isinstance(p, FitParam) for p in ps):
            return list(ps)  # type: ignore[arg-type]
        names = None if ps is None else [p.name if isinstance(p, FitParam) else p for p in ps]
        return resolve_params(self.model, names, self.bounds)

    def fit(self, drops: list[Drop], validation: list[Drop] | None = None) -> Identifier:
        """Identify the parameters from ``drops`` (``validation``: drops it reports the fitted
        model's NRMSE on, never fitted to). Returns the identifier, fitted."""
        if not drops:
            raise FitError("no drops to fit")
        for name in ("cma_evals", "ls_evals"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise FitError(f"{name} must be a whole number, 0 or more, not {v!r}")
        if self.workers is not None and (not isinstance(self.workers, int) or self.workers < 1):
            raise FitError(f"workers must be a whole number, 1 or more, not {self.workers!r}")
        self.result_ = _search(self, list(drops), validation)
        return self

    @property
    def model_(self) -> Model:
        return self._fitted().model

    @property
    def values_(self) -> dict[str, float]:
        return dict(self._fitted().values)

    def predict(self, drops: list[Drop]) -> list[np.ndarray]:
        """The fitted model's six states at each drop's sample times."""
        return [predict(self.model_, d, outcome=False)[0] for d in drops]

    def score(self, drops: list[Drop]) -> float:
        """The fitted model's combined NRMSE on ``drops`` (the paper's measure: lower is
        better, unlike scikit-learn's scores), normalised by this fit's state ranges."""
        ranges = self.ranges if self.ranges is not None else self._fitted().ranges
        return compare(self.model_, drops, ranges).nrmse

    def _fitted(self) -> FitResult:
        if self.result_ is None:
            raise FitError("this identifier is not fitted yet: call fit(drops) first")
        return self.result_


def _search(ident: Identifier, drops: list[Drop], validation: list[Drop] | None) -> FitResult:
    """CMA-ES from the start, then least squares; intervals and warnings at the optimum."""
    import cma
    from scipy.optimize import least_squares

    t0 = time.perf_counter()
    model, seed, sigma, workers = ident.model, ident.seed, ident.sigma, ident.workers
    cma_evals, ls_evals = ident.cma_evals, ident.ls_evals
    params = ident.fit_params()
    ranges = state_ranges(drops + (validation or [])) if ident.ranges is None else ident.ranges
    prob = Problem(model, drops, params, ranges)
    n = len(params)
    tick = ident.progress or (lambda k: None)
    here = {} if ident.from_centre else {p.name: model.parameter(p.name) for p in params}
    start = {**here, **(ident.start or {})}
    x0 = np.array([p.unit(start[p.name]) if p.name in start else 0.5 for p in params])
    x0 = np.clip(x0, 0.0, 1.0)
    start_values = dict(zip([p.name for p in params], prob.values(x0), strict=True))
    with Evaluator(prob, workers, ident.client) as ev:
        best_u, best_c = x0, math.inf
        firsts = [x0]
        for extra in ident.also or []:
            merged = {**(ident.start or {}), **extra}
            point = [p.unit(merged[p.name]) if p.name in merged else 0.5 for p in params]
            firsts.append(np.clip(point, 0.0, 1.0))
        costs0 = [float(r @ r) for r in ev.residuals(firsts)]
        start_cost = costs0[0]
        i0 = int(np.argmin(costs0))
        best_u, best_c = np.asarray(firsts[i0], dtype=float), costs0[i0]
        if cma_evals > 0 and n == 1:  # CMA-ES needs two dimensions: scan the line instead
            X = [np.array([x]) for x in np.linspace(0.0, 1.0, max(3, min(cma_evals, 41)))]
            costs = [float(r @ r) for r in ev.residuals(X)]
            tick(len(X))
            i = int(np.argmin(costs))
            if costs[i] < best_c:
                best_u, best_c = X[i].copy(), costs[i]
        elif cma_evals > 0:
            # even, whatever the number of processes: a seed gives the same search on any machine
            popsize = max(8, 4 + int(3 * math.log(n)))
            popsize += popsize % 2
            origins = [x0]
            for point in ident.starts or []:
                origins.append(
                    np.clip([p.unit(point[p.name]) if p.name in point else 0.5 for p in params], 0.0, 1.0)
                )
            for run in range(max(0, ident.restarts)):
                origins.append(np.random.default_rng(seed + 1 + run).uniform(0.2, 0.8, n))
            runs = len(origins)
            for run, origin in enumerate(origins):
                es = cma.CMAEvolutionStrategy(
                    list(origin),
                    sigma,
                    {
                        "bounds": [0, 1],
                        "popsize": popsize,
                        "seed": seed + 1 + 100 * run,
                        "verbose": -9,
                        "maxfevals": cma_evals // runs,
                        "tolfun": 1e-10,
                    },
                )
                while not es.stop():
                    X = es.ask()
                    rs = ev.residuals([np.asarray(x) for x in X])
                    costs = [float(r @ r) for r in rs]
                    es.tell(X, costs)
                    tick(len(X))
                    i = int(np.argmin(costs))
                    if costs[i] < best_c:
                        best_u, best_c = np.asarray(X[i], dtype=float).copy(), costs[i]
        cache: dict[bytes, np.ndarray] = {}

        def fun(u: np.ndarray) -> np.ndarray:
            key = np.asarray(u).tobytes()
            if key not in cache:
                cache[key] = ev.residuals([np.asarray(u)])[0]
                tick(1)
            return cache[key]

        jacs: dict[bytes, np.ndarray] = {}

        def jac(u: np.ndarray) -> np.ndarray:
            # kept: the intervals need the Jacobian at the optimum, where the polish has
            # usually just computed it
            key = np.asarray(u, dtype=float).tobytes()
            if key not in jacs:
                jacs[key] = _jacobian(ev, np.asarray(u, dtype=float), fun(u))
                tick(len(u))
            return jacs[key]

        u = best_u
        if ls_evals > 0:  # 0: the search's best point as it is, no polish
            ls = least_squares(
                fun,
                np.clip(best_u, 1e-6, 1 - 1e-6),
                jac=jac,
                bounds=(0.0, 1.0),
                x_scale="jac",
                max_nfev=ls_evals,
                xtol=1e-8,
                ftol=1e-10,
                gtol=1e-10,
            )
            if 2 * ls.cost <= best_c:
                u = ls.x
        r = fun(u)
        J = jac(u)
        values = dict(zip([p.name for p in params], prob.values(u), strict=True))
        ci, warns = identifiability(params, J, u, r, values, prob.groups())
        nfev = ev.nfev
    fitted = apply(model, params, [values[p.name] for p in params])
    train = compare(fitted, drops, ranges).nrmse
    val = compare(fitted, validation, ranges).nrmse if validation else None
    start_nrmse = compare(apply(model, params, list(start_values.values())), drops, ranges).nrmse
    if train > start_nrmse * (1 + 1e-9):
        warns.append(
            f"the fit's training NRMSE {train:.4f} is worse than its start's {start_nrmse:.4f} "
            f"(its cost, the sum of squares it minimises, is not: {float(r @ r):.4g} <= {start_cost:.4g})"
        )
    return FitResult(
        params,
        values,
        u,
        float(r @ r),
        train,
        ci,
        warns,
        nfev,
        time.perf_counter() - t0,
        fitted,
        val,
        [d.name for d in drops],
        [d.name for d in validation or []],
        start_values,
        start_cost,
        start_nrmse,
        ranges,
    )


def fit(
    model: Model,
    drops: list[Drop],
    params: list[FitParam] | None = None,
    *,
    validation: list[Drop] | None = None,
    **settings: object,
) -> FitResult:
    """Deprecated: ``Identifier(model, params, **settings).fit(drops, validation).result_``."""
    warnings.warn(
        "slopelander.ident.fit.fit is deprecated: use Identifier(model, params, ...).fit(drops)",
        DeprecationWarning,
        stacklevel=2,
    )
    ident = Identifier(model, params, **settings)  # type: ignore[arg-type]
    return ident.fit(drops, validation)._fitted()


def subsets(
    n: int, repeats: int = 3, train: int | None = None, seed: int = 0
) -> list[tuple[list[int], list[int]]]:
    """Training / validation index splits: by default 3 x (60 % / 40 %), as the paper's
    three fits of 6 drops validated on the other 4."""
    train = round(0.6 * n) if train is None else train
    if not 1 <= train < n:
        raise FitError(f"need at least one training and one validation drop (have {n} drops, train {train})")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(repeats):
        perm = rng.permutation(n)
        out.append((sorted(perm[:train].tolist()), sorted(perm[train:].tolist())))
    return out


@dataclass
class SubsetFits:
    """Fits repeated over training subsets: the Table-II-style summary."""

    fits: list[FitResult]

    def mean_sd(self) -> dict[str, tuple[float, float]]:
        names = [p.name for p in self.fits[0].params]
        return {
            n: (
                float(np.mean([f.values[n] for f in self.fits])),
                float(np.std([f.values[n] for f in self.fits], ddof=1)) if len(self.fits) > 1 else 0.0,
            )
            for n in names
        }

    @property
    def train_nrmse(self) -> float:
        return float(np.mean([f.train_nrmse for f in self.fits]))

    @property
    def validation_nrmse(self) -> float:
        return float(np.mean([f.validation_nrmse for f in self.fits if f.validation_nrmse is not None]))

    def warnings(self) -> list[str]:
        seen = []
        for f in self.fits:
            for w in f.warnings:
                if w.split(":")[0] not in [s.split(":")[0] for s in seen]:
                    seen.append(w)
        return seen

    def table(self) -> str:
        lines = ["| parameter | mean | sigma | 95 % CI (first fit) |", "|---|---:|---:|---:|"]
        for n, (m, s) in self.mean_sd().items():
            lines.append(f"| {n} | {m:.4g} | {s:.2g} | +-{self.fits[0].ci95[n]:.2g} |")
        lines.append("")
        lines.append(
            f"NRMSE training {self.train_nrmse:.4f}, validation {self.validation_nrmse:.4f} "
            f"(mean of {len(self.fits)} fits)"
        )
        return "\n".join(lines)


def fit_subsets(
    ident: Identifier | Model,
    drops: list[Drop],
    params: list[FitParam] | None = None,
    *,
    repeats: int = 3,
    train: int | None = None,
    seed: int = 0,
    **settings,
) -> SubsetFits:
    """The paper's procedure: ``repeats`` fits on different training subsets, each validated on
    the drops it did not see. ``ident`` is the configured :class:`Identifier` (or a model, with
    ``params`` and ``settings`` those of an Identifier)."""
    if not isinstance(ident, Identifier):
        ident = Identifier(ident, params, **settings)
    ident = ident.with_(ranges=state_ranges(drops))
    fits = []
    for k, (tr, va) in enumerate(subsets(len(drops), repeats, train, seed)):
        one = ident.with_(seed=seed + k).fit([drops[i] for i in tr], [drops[i] for i in va])
        fits.append(one._fitted())
    return SubsetFits(fits)
