"""Identify named model parameters from recorded drops, as the paper did (Sec. IV-D).

A global search (CMA-ES by default, any :class:`~slopelander.ident.optimizers.Optimizer`
given; from the given model's values, or from the centre of the bounds when asked) then a
local least-squares polish with a finite-difference Jacobian whose columns are simulated in
parallel. The Jacobian at the optimum also gives confidence intervals and shows
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
from threadpoolctl import threadpool_limits

from slopelander.errors import SlopelanderError
from slopelander.ident.clocks import align_windows, aligned
from slopelander.ident.compare import WEIGHTS, compare, state_ranges
from slopelander.ident.observe import predict
from slopelander.ident.optimizers import CMA, Optimizer, SearchTask
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
    """Residuals of a model over a set of drops as a function of the unit-cube parameters.

    ``align``: per drop, how far (s) its clock may be off the model's (its t = 0 off the
    contact, its frames lagging): each evaluation observes the model at the lag within
    +-align that fits that drop best (:func:`slopelander.ident.clocks.aligned`); 0 (the
    default) observes at t."""

    model: Model
    drops: list[Drop]
    params: list[FitParam]
    ranges: np.ndarray
    align: Sequence[float] | None = None

    def __post_init__(self) -> None:
        self.align = [0.0] * len(self.drops) if self.align is None else [float(a) for a in self.align]
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
            _, r = self._lag(m, i)
            out.append(r[self._seen[i]] if self._gaps else r.ravel())
        r = np.concatenate(out)
        return np.where(np.isfinite(r), r, 10.0)

    def lags(self, u: Sequence[float]) -> list[float]:
        """The lag (s) each drop is observed at, at ``u`` (0 where it is not aligned)."""
        m = self.model_at(u)
        return [self._lag(m, i)[0] if a > 0 else 0.0 for i, a in enumerate(self.align)]

    def _lag(self, m: Model, i: int) -> tuple[float, np.ndarray]:
        """Drop ``i``'s lag and residual: at t with no window, else at the lag within its
        window that makes the residual least."""
        sim, _, lag = aligned(m, self.drops[i], self.align[i], self._scale[i])
        return lag, (sim[self._after[i]] - self._measured[i]) * self._scale[i]

    def groups(self) -> np.ndarray:
        """The drop each residual belongs to (for intervals over drops)."""
        return np.concatenate([np.full(int(s.sum()), i) for i, s in enumerate(self._seen)])

    @property
    def size(self) -> int:
        return sum(int(s.sum()) for s in self._seen)

    def cost(self, u: Sequence[float]) -> float:
        r = self.residuals(u)
        return float(r @ r)


def windows(drops: Sequence[Drop], align_s: float | Sequence[float] | None) -> list[float]:
    """:func:`~slopelander.ident.clocks.align_windows`, refused as a :class:`FitError`;
    ``align_s`` may also give each drop its own window."""
    if isinstance(align_s, (list, tuple)):
        if len(align_s) != len(drops):
            raise FitError(f"align_s: {len(align_s)} windows for {len(drops)} drops")
        return [w for a in align_s for w in windows(drops[:1], a)]
    try:
        return align_windows(drops, align_s)
    except ValueError as exc:
        raise FitError(f"align_s: {exc}") from None


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
    """Half-width of the 95 % confidence interval, Student's t with drops - 1 degrees of freedom:
    the sandwich over drops (each drop one independent unit), or with ``intervals="jackknife"``
    the spread of the refits that each leave one drop out."""
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
    intervals: str = "sandwich"
    """How :attr:`ci95` was made (:data:`INTERVALS`)."""
    lags: dict[str, float] = field(default_factory=dict)
    """s, per drop aligned (``align_s``): the lag the fitted model observes it at."""


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


INTERVAL_STEP = 1e-2
"""The step (a share of each parameter's bounds) of the central differences the intervals and
the flat directions are read from. The cost is piecewise (a foot sticks or slips, a contact
starts a sample sooner): at the polish's 1e-3 the slope seen is the nearest kink's, and the
sandwich's widths varied tenfold between noise seeds, holding the truth of the model's own
drops in 4 of 12 fits; at 1e-2 they agree with 2e-2's within about 10 % and held it in 12 of
12 (benchmarks/interval_coverage.py has the counts over 20 seeds)."""


def _interval_jacobian(ev: Evaluator, u: np.ndarray, h: float = INTERVAL_STEP) -> np.ndarray:
    """Central differences at ``h`` (one-sided where a bound is nearer than ``h``)."""
    pts, spans = [], []
    for i in range(len(u)):
        lo, hi = u.copy(), u.copy()
        lo[i], hi[i] = max(u[i] - h, 0.0), min(u[i] + h, 1.0)
        pts += [hi, lo]
        spans.append(hi[i] - lo[i])
    cols = ev.residuals(pts)
    return np.column_stack([(cols[2 * i] - cols[2 * i + 1]) / d for i, d in enumerate(spans)])


FLAT = 1e-3
"""A direction whose singular value is below this share of the largest is flat: the data
barely constrain it."""


def _flat(params: list[FitParam], J: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Which parameters load on a flat direction of ``J`` (the pseudo-inverse drops such a
    direction and would read them as perfectly known), and a warning per flat direction."""
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    unknown = np.zeros(len(params), dtype=bool)
    if not (sv.size and sv[0] > 0):
        for k in range(len(sv)):  # no direction is constrained at all
            unknown |= np.abs(Vt[k]) > 0.1
        return unknown, []
    warnings = []
    for k in np.flatnonzero(sv / sv[0] < FLAT):
        lead = [params[i].name for i in np.argsort(-np.abs(Vt[k]))[:2]]
        warnings.append(
            f"flat direction: the data barely constrain a combination of "
            f"{' and '.join(lead)} (singular value ratio {sv[k] / sv[0]:.1e})"
        )
    for k in np.flatnonzero(sv <= sv[0] * FLAT):
        unknown |= np.abs(Vt[k]) > 0.1
    return unknown, warnings


def covariance(J: np.ndarray, r: np.ndarray, groups: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """The unit-cube parameters' covariance and the 95 % quantile its intervals use.

    With ``groups`` (the drop of each residual, more than one drop) the sandwich over drops:
    each drop's summed score J_i^T r_i one observation, Student's t with drops - 1 degrees of
    freedom. Without, the Gauss-Newton covariance, every sample independent (optimistic)."""
    JtJ = J.T @ J
    ids = np.unique(groups) if groups is not None else np.zeros(1)
    if len(ids) < 2:
        s2 = float(r @ r) / max(len(r) - J.shape[1], 1)
        return np.linalg.pinv(JtJ) * s2, 1.96
    from scipy.stats import t as student

    scores = np.array([J[groups == g].T @ r[groups == g] for g in ids])
    inv = np.linalg.pinv(JtJ)
    cov = inv @ (scores.T @ scores) @ inv * len(ids) / (len(ids) - 1)
    return cov, float(student.ppf(0.975, len(ids) - 1))


def _value_warnings(p: FitParam, v: float, half: float, u: float, unknown: bool) -> list[str]:
    """What a user should know of one fitted value: not identified, poorly, or at its bound."""
    out = []
    if unknown:
        out.append(
            f"{p.name} is not identified: the drops do not change with it near {v:.3g} "
            "(no interval can be given)"
        )
    elif half > 0.5 * abs(v) and abs(v) > 0:
        out.append(f"{p.name} is poorly identified: 95 % interval +-{half:.3g} on a value of {v:.3g}")
    if u < 0.01 or u > 0.99:
        out.append(
            f"{p.name} = {v:.3g} sits at its bound ({p.low:g}..{p.high:g}): widen the bounds "
            "or the data do not need it"
        )
    return out


def _correlated(params: list[FitParam], cov: np.ndarray, unknown: np.ndarray) -> list[str]:
    d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(d, d)
    return [
        f"{params[i].name} and {params[j].name} are correlated "
        f"(rho = {corr[i, j]:+.2f}): the data fix their combination, not each"
        for i in range(len(params))
        for j in range(i + 1, len(params))
        if abs(corr[i, j]) > 0.95 and not (unknown[i] or unknown[j])
    ]


def identifiability(
    params: list[FitParam],
    J: np.ndarray,
    u: np.ndarray,
    r: np.ndarray,
    values: dict[str, float],
    groups: np.ndarray | None = None,
    cov: tuple[np.ndarray, float] | None = None,
    halves: np.ndarray | None = None,
) -> tuple[dict[str, float], list[str]]:
    """95 % half-widths and warnings for parameters the data cannot identify: a flat direction
    (tiny singular value), a strong correlation, or an interval wider than half the value.

    With ``groups`` (the drop of each residual), the covariance is the sandwich over drops:
    the drops are the independent units, the samples inside one are not (rates are slopes over
    several samples, a model error is one smooth curve), so each drop's summed score J_i^T r_i
    is one observation; the half-width uses Student's t with (drops - 1) degrees of freedom.
    Without, the Gauss-Newton covariance treats every sample as independent (optimistic).
    ``cov`` (the unit-cube covariance and its 95 % quantile, e.g. :func:`jackknife`) replaces
    either; the flat directions are still read from ``J``. ``halves`` (unit-cube 95 % half-widths,
    e.g. from the profiles, :mod:`slopelander.ident.profile`) replace the covariance's own."""
    unknown, warnings = _flat(params, J)
    cov, quantile = covariance(J, r, groups) if cov is None else cov
    half_u = quantile * np.sqrt(np.clip(np.diag(cov), 0, None)) if halves is None else halves
    ci = {}
    for i, p in enumerate(params):
        ci[p.name] = math.inf if unknown[i] else float(half_u[i]) * p.slope(float(u[i]))
        warnings += _value_warnings(p, values[p.name], ci[p.name], float(u[i]), bool(unknown[i]))
    return ci, warnings + _correlated(params, cov, unknown)


INTERVALS = ("sandwich", "jackknife", "profile")
"""The kinds of 95 % interval a fit prints: the sandwich over drops, the leave-one-drop-out
jackknife of refits (:func:`jackknife`), or each parameter's profile with the drops as units
(:mod:`slopelander.ident.profile`)."""
INTERVAL_WORDS = {
    "sandwich": "over drops",
    "jackknife": "by the jackknife, one drop left out at a time",
    "profile": "from each value's profile, over drops",
}
"""How each kind of interval is named where it is printed."""


def jackknife(refits: list[np.ndarray]) -> tuple[np.ndarray, float]:
    """The unit-cube covariance of a fit from its leave-one-drop-out refits (one per drop) and
    the 95 % quantile its intervals use: ``(n - 1) / n`` times the refits' summed squared
    deviations from their mean (Tukey's jackknife), Student's t with n - 1 degrees of freedom.
    It reads no curvature off a Jacobian, and a model error that moves the estimate differently
    from drop to drop shows as spread; but a refit can stay at the fit's kink of the piecewise
    cost (its spread then reads too small: 15 and 11 of 20 intervals held the truth where the
    sandwich at :data:`INTERVAL_STEP` held 20 and 20, benchmarks/interval_coverage.py)."""
    from scipy.stats import t as student

    U = np.asarray(refits, dtype=float)
    n = len(U)
    if n < 2:
        raise FitError("a jackknife needs at least two drops")
    d = U - U.mean(axis=0)
    return d.T @ d * (n - 1) / n, float(student.ppf(0.975, n - 1))


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
    ``optimizer`` is the global search (:mod:`slopelander.ident.optimizers`; default
    :class:`~slopelander.ident.optimizers.CMA`), given ``cma_evals`` evaluations whichever it is.
    ``intervals``: how the 95 % intervals are made, ``"sandwich"`` (over drops, from central
    differences at :data:`INTERVAL_STEP` at the optimum: cheap), ``"jackknife"`` (one polish
    per drop left out, from the optimum, ``ls_evals`` each; :func:`jackknife`) or ``"profile"``
    (each parameter's profile, :mod:`slopelander.ident.profile`: the dearest; a lower cost met
    on the way moves the fit on, and says so in the warnings).

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
    optimizer: Optimizer | None = None
    intervals: str = "sandwich"
    align_s: float | Sequence[float] | None = None
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
        if self.intervals not in INTERVALS:
            raise FitError(f"intervals must be one of {', '.join(INTERVALS)}, not {self.intervals!r}")
        if self.intervals == "jackknife" and (len(drops) < 3 or self.ls_evals < 1):
            raise FitError(
                "jackknife intervals need at least 3 drops and ls_evals of 1 or more (each drop left "
                f"out is refitted by least squares): have {len(drops)} drops, ls_evals {self.ls_evals}"
            )
        if self.optimizer is not None and not isinstance(self.optimizer, Optimizer):
            raise FitError(
                f"optimizer must be an object with a name and a search(task) method, e.g. CMA() or "
                f"DifferentialEvolution() from slopelander.ident.optimizers, not {self.optimizer!r}"
            )
        self.result_ = _search(self, list(drops), validation)
        return self

    @property
    def model_(self) -> Model:
        return self._fitted().model

    def jackknife_ci95(self, drops: list[Drop]) -> dict[str, float]:
        """95 % half-widths of the fitted values by the leave-one-drop-out jackknife
        (:func:`jackknife`) around this fit's optimum on ``drops`` (those it was fitted to), as
        ``intervals="jackknife"`` prints them: to compare the two kinds on one fit."""
        res = self._fitted()
        prob = Problem(self.model, list(drops), res.params, res.ranges, windows(drops, self.align_s))
        cov, q = jackknife(_leave_one_out(self, prob, res.u))
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        return {p.name: q * sd[i] * p.slope(float(res.u[i])) for i, p in enumerate(res.params)}

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
        return compare(self.model_, drops, ranges, windows(drops, self.align_s)).nrmse

    def _fitted(self) -> FitResult:
        if self.result_ is None:
            raise FitError("this identifier is not fitted yet: call fit(drops) first")
        return self.result_


def _start(params: list[FitParam], point: dict[str, float], base: dict[str, float]) -> np.ndarray:
    """A point of the unit cube from values by name: ``point`` over ``base``, the centre of the
    bounds for a parameter named in neither."""
    merged = {**base, **point}
    return np.clip([p.unit(merged[p.name]) if p.name in merged else 0.5 for p in params], 0.0, 1.0)


def _origins(ident: Identifier, params: list[FitParam], x0: np.ndarray) -> list[np.ndarray]:
    """Where the global search's runs begin: the start, each of ``starts``, then ``restarts``
    random points (seeded) away from the bounds."""
    origins = [x0]
    origins += [_start(params, point, {}) for point in ident.starts or []]
    for run in range(max(0, ident.restarts)):
        origins.append(np.random.default_rng(ident.seed + 1 + run).uniform(0.2, 0.8, len(params)))
    return origins


KINK_STEP = 0.02
"""The side of the polish's simplex over the kinks, in units of each parameter's bounds."""


class _Polish:
    """The polish's residuals and least-squares Jacobians, each point evaluated once."""

    def __init__(self, ev: Evaluator, tick: Callable[[int], None]) -> None:
        self.ev, self.tick = ev, tick
        self._r: dict[bytes, np.ndarray] = {}
        self._J: dict[bytes, np.ndarray] = {}

    def fun(self, u: np.ndarray) -> np.ndarray:
        key = np.asarray(u).tobytes()
        if key not in self._r:
            self._r[key] = self.ev.residuals([np.asarray(u)])[0]
            self.tick(1)
        return self._r[key]

    def jac(self, u: np.ndarray) -> np.ndarray:
        key = np.asarray(u, dtype=float).tobytes()
        if key not in self._J:
            self._J[key] = _jacobian(self.ev, np.asarray(u, dtype=float), self.fun(u))
            self.tick(len(u))
        return self._J[key]

    def run(self, u: np.ndarray, cost: float, max_nfev: int) -> np.ndarray:
        """Least squares from ``u`` (whose cost is ``cost``), then a step over the kinks
        (:meth:`over_kinks`); the best point of the three."""
        if max_nfev <= 0:  # 0: the search's best point as it is, no polish
            return u
        from scipy.optimize import least_squares

        ls = least_squares(
            self.fun,
            np.clip(u, 1e-6, 1 - 1e-6),
            jac=self.jac,
            bounds=(0.0, 1.0),
            x_scale="jac",
            max_nfev=max_nfev,
            xtol=1e-8,
            ftol=1e-10,
            gtol=1e-10,
        )
        if 2 * ls.cost <= cost:
            u, cost = ls.x, 2 * ls.cost
        return self.over_kinks(u, cost, max_nfev)

    def over_kinks(self, u: np.ndarray, cost: float, max_nfev: int) -> np.ndarray:
        """Nelder-Mead from ``u`` with a simplex :data:`KINK_STEP` wide: the cost is piecewise
        (a foot sticks or slips, a contact starts a sample sooner), and least squares stops at a
        kink where its trust region shrinks to nothing. Drops of a known truth showed it: a fit
        ended 5 % off (k_g 28,649 against 30,000) at a cost 15 % above a point 1,300 N/m away
        that the simplex, stepping over the kink, finds in 40 evaluations."""
        from scipy.optimize import minimize

        n = len(u)
        start = np.clip(u, 0.0, 1.0 - KINK_STEP)
        simplex = np.vstack([start, start + KINK_STEP * np.eye(n)])
        nm = minimize(
            lambda v: float(self.fun(v) @ self.fun(v)),
            start,
            method="Nelder-Mead",
            bounds=[(0.0, 1.0)] * n,
            options={"maxfev": max(max_nfev, n + 2), "initial_simplex": simplex, "xatol": 1e-6, "fatol": 0.0},
        )
        return nm.x if nm.fun < cost else u


def _global_search(
    ident: Identifier, ev: Evaluator, params: list[FitParam], x0: np.ndarray
) -> tuple[SearchTask, float]:
    """The start and the points in ``also`` evaluated first, then the optimizer's search: the
    task (holding the best point seen) and the start's cost."""

    def evaluate(points: list[np.ndarray]) -> list[float]:
        return [float(r @ r) for r in ev.residuals(points)]

    firsts = [x0] + [_start(params, extra, ident.start or {}) for extra in ident.also or []]
    costs0 = evaluate(firsts)
    i0 = int(np.argmin(costs0))
    task = SearchTask(
        evaluate,
        _origins(ident, params, x0),
        budget=ident.cma_evals,
        seed=ident.seed,
        sigma=ident.sigma,
        best_u=np.asarray(firsts[i0], dtype=float),
        best_cost=costs0[i0],
        progress=ident.progress or (lambda k: None),
    )
    (ident.optimizer or CMA()).search(task)
    return task, costs0[0]


def _problem(ident: Identifier, drops: list[Drop], validation: list[Drop] | None = None) -> Problem:
    """``ident``'s residuals over ``drops``: its parameters, its states' ranges (those of the
    drops fitted and validated on unless fixed) and each drop's clock window."""
    ranges = state_ranges(drops + (validation or [])) if ident.ranges is None else ident.ranges
    return Problem(ident.model, drops, ident.fit_params(), ranges, windows(drops, ident.align_s))


def scan(
    ident: Identifier,
    drops: list[Drop],
    names: Sequence[str],
    anchors: Sequence[dict[str, float]],
    n: int = 128,
) -> tuple[dict[str, float], float]:
    """The best of ``n`` points per anchor (a scrambled Sobol set, seeded by ``ident.seed``)
    spread over the bounds of the parameters ``names``, the others of ``ident`` held at each
    anchor's values (the model's own where an anchor names none): its values by name and its
    cost. For a valley too thin for a search from one side to enter: round pads' radius and
    inset trade along a curve where a landing's reach stays the same, and a drop whose outcome
    switches (a flip, a slide) makes the cost rough across it; a refit from the groups' mean
    ended with the legs' flex at its bound and the pads at 3.1 noise floors, a scan anchored
    there found nothing better, one anchored at the model's own values found the valley
    (benchmarks/results/2026-12-08-pad-scan.md)."""
    from scipy.stats import qmc

    prob = _problem(ident, drops)
    params = prob.params
    free = [i for i, p in enumerate(params) if p.name in names]
    if not free:
        raise FitError(f"none of {', '.join(names)} is fitted here")
    here = {p.name: ident.model.parameter(p.name) for p in params}
    cube = qmc.Sobol(len(free), seed=ident.seed).random(n)
    points = []
    for anchor in anchors:
        u0 = _start(params, anchor, here)
        for q in cube:
            u = u0.copy()
            u[free] = q
            points.append(u)
    with threadpool_limits(1), Evaluator(prob, ident.workers, ident.client) as ev:
        costs = [float(r @ r) for r in ev.residuals(points)]
        (ident.progress or (lambda k: None))(len(points))
    best = int(np.argmin(costs))
    return dict(zip([p.name for p in params], prob.values(points[best]), strict=True)), costs[best]


def _search(ident: Identifier, drops: list[Drop], validation: list[Drop] | None) -> FitResult:
    """The global search from the start, then least squares; intervals and warnings at the optimum."""
    t0 = time.perf_counter()
    prob = _problem(ident, drops, validation)
    params = prob.params
    here = {} if ident.from_centre else {p.name: ident.model.parameter(p.name) for p in params}
    x0 = _start(params, ident.start or {}, here)
    # the search's own linear algebra (tall, narrow matrices) on one thread: threaded BLAS gains
    # nothing on them and, beside the processes that simulate, its threads wait for the cores
    # (an SVD of the polish 10-100x slower on a busy 2-core machine); the results are the same
    with threadpool_limits(1), Evaluator(prob, ident.workers, ident.client) as ev:
        task, start_cost = _global_search(ident, ev, params, x0)
        polish = _Polish(ev, ident.progress or (lambda k: None))
        u = polish.run(task.best_u, task.best_cost, ident.ls_evals)
        r, J = polish.fun(u), _interval_jacobian(ev, np.asarray(u, dtype=float))
        polish.tick(2 * len(u))
        cov, stuck, halves, warns = None, [], None, []
        if ident.intervals == "profile":
            u, r, J, halves, warns = _profiles(ident, ev, polish, prob, u, r, J)
        values = dict(zip([p.name for p in params], prob.values(u), strict=True))
        if ident.intervals == "jackknife":
            refits = _leave_one_out(ident, prob, u)
            cov = jackknife(refits)
            stuck = [k for k, v in enumerate(refits) if np.array_equal(v, u)]
        ci, more = identifiability(params, J, u, r, values, prob.groups(), cov, halves)
        warns += more
        if 2 * len(stuck) >= len(prob.drops):
            warns.append(
                f"jackknife: {len(stuck)} of {len(prob.drops)} refits without one drop ended where the "
                "fit did (the least-squares polish found nothing lower on this piecewise cost): the "
                "intervals understate the spread; more --ls-evals, or compare with the sandwich"
            )
        nfev = ev.nfev
    return _result(
        ident,
        prob,
        u,
        r,
        ci=ci,
        warnings=warns,
        nfev=nfev,
        start=dict(zip([p.name for p in params], prob.values(x0), strict=True)),
        start_cost=start_cost,
        validation=validation,
        seconds=time.perf_counter() - t0,
    )


PROFILE_ROUNDS = 3
"""How often a profile that meets a lower cost than the fit's moves the fit there and starts
again (then the intervals are read about the last point, lower or not)."""


def _profiles(
    ident: Identifier,
    ev: Evaluator,
    polish: _Polish,
    prob: Problem,
    u: np.ndarray,
    r: np.ndarray,
    J: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Profile intervals (:mod:`slopelander.ident.profile`): a coarse scan of each parameter for
    a lower cost than the fit's (the search stopped short: polished on from there, said), then
    each parameter's profile about the optimum, its first span twice the sandwich's half-width.
    The point, its residual and interval Jacobian, the unit-cube half-widths and warnings."""
    from slopelander.ident import profile

    tick = ident.progress or (lambda k: None)
    params, warns = prob.params, []
    cost = float(r @ r)

    def go_on(point: np.ndarray, c: float, name: str) -> None:
        nonlocal u, r, cost
        moved = polish.run(point, c, ident.ls_evals)
        r_new = polish.fun(moved)
        warns.append(
            f"the search had stopped short: {name}'s profile found a cost {float(r_new @ r_new):.4g} "
            f"below the fit's {cost:.4g}; the fit goes on from there"
        )
        u, r, cost = np.asarray(moved, dtype=float), r_new, float(r_new @ r_new)

    j_at = u  # the caller's J is at the caller's u
    for k, p in enumerate(params):
        best, c = profile.coarse_scan(ev.residuals, u, k, ident.ls_evals, tick)
        if c < cost * (1 - 1e-6):
            go_on(best, c, p.name)
    halves, groups = np.empty(len(params)), prob.groups()
    for rnd in range(PROFILE_ROUNDS):
        if u is not j_at:  # the fit moved on: the slopes the first spans come from, there
            J, j_at = _interval_jacobian(ev, u), u
            tick(2 * len(u))
        sandwich, quantile = covariance(J, r, groups)
        spans = 2 * quantile * np.sqrt(np.clip(np.diag(sandwich), 0, None))
        notes, lower = [], None
        for k, p in enumerate(params):
            prof = profile.profile_interval(ev.residuals, u, groups, k, float(spans[k]), ident.ls_evals, tick)
            halves[k] = prof.half_about(float(u[k]))
            notes += [f"{p.name}: {prof.note}"] if prof.note else []
            last = rnd == PROFILE_ROUNDS - 1
            if prof.lowest is not None and prof.lowest_cost < cost * (1 - 1e-6) and not last:
                lower = (prof.lowest, prof.lowest_cost, p.name)
                break
        if lower is None:
            break
        go_on(*lower)
    warns += notes
    return u, r, J, halves, warns


def _leave_one_out(ident: Identifier, prob: Problem, u: np.ndarray) -> list[np.ndarray]:
    """The optimum ``u`` refitted by least squares (``ident.ls_evals``) once per drop, that drop
    left out, on the same state ranges."""
    out = []
    for i in range(len(prob.drops)):
        rest = [d for k, d in enumerate(prob.drops) if k != i]
        align = [w for k, w in enumerate(prob.align) if k != i]
        sub = Problem(ident.model, rest, prob.params, prob.ranges, align)
        with Evaluator(sub, ident.workers, ident.client) as ev:
            polish = _Polish(ev, ident.progress or (lambda k: None))
            r0 = polish.fun(u)
            out.append(polish.run(u, float(r0 @ r0), ident.ls_evals))
    return out


def _result(
    ident: Identifier,
    prob: Problem,
    u: np.ndarray,
    r: np.ndarray,
    *,
    ci: dict[str, float],
    warnings: list[str],
    nfev: int,
    start: dict[str, float],
    start_cost: float,
    validation: list[Drop] | None,
    seconds: float,
) -> FitResult:
    """The fit's result at ``u``: the fitted model, its NRMSEs, and a warning when the training
    NRMSE ended worse than the start's (the cost never does)."""
    params, drops, ranges = prob.params, prob.drops, prob.ranges
    values = dict(zip([p.name for p in params], prob.values(u), strict=True))
    fitted = apply(ident.model, params, [values[p.name] for p in params])
    train = compare(fitted, drops, ranges, prob.align).nrmse
    start_nrmse = compare(apply(ident.model, params, list(start.values())), drops, ranges, prob.align).nrmse
    if train > start_nrmse * (1 + 1e-9):
        warnings.append(
            f"the fit's training NRMSE {train:.4f} is worse than its start's {start_nrmse:.4f} "
            f"(its cost, the sum of squares it minimises, is not: {float(r @ r):.4g} <= {start_cost:.4g})"
        )
    return FitResult(
        params=params,
        values=values,
        u=u,
        cost=float(r @ r),
        train_nrmse=train,
        ci95=ci,
        warnings=warnings,
        nfev=nfev,
        seconds=seconds,
        model=fitted,
        validation_nrmse=(
            compare(fitted, validation, ranges, windows(validation, ident.align_s)).nrmse
            if validation
            else None
        ),
        train_names=[d.name for d in drops],
        validation_names=[d.name for d in validation or []],
        start_values=start,
        start_cost=start_cost,
        start_nrmse=start_nrmse,
        ranges=ranges,
        intervals=ident.intervals,
        lags={d.name: lag for d, lag, w in zip(drops, prob.lags(u), prob.align, strict=True) if w > 0},
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
