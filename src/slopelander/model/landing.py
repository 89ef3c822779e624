"""Whole landings: the model object, one simulated landing, and the batch path."""

from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numba
import numpy as np

from slopelander.model import kernel as k
from slopelander.model.conditions import (
    MAX_REVERSE_DURATION,
    MAX_REVERSE_RAMP,
    LandingConditions,
    conditions_array,
)
from slopelander.model.dispatch import call
from slopelander.model.effects import (
    BUILTIN_EFFECTS,
    EffectError,
    EffectParameter,
    UserEffect,
    check_effect_names,
    check_user_effects,
    flags_for,
    memory_slots,
)
from slopelander.model.outcome import RESULT_DTYPE, RESULT_FIELDS, Outcome, OutcomeCriteria
from slopelander.model.parameters import ModelParams
from slopelander.model.seams import seam_table
from slopelander.model.usercode import compiling_notice

STATE_COLUMNS: tuple[int, ...] = (k.S_Q, k.S_Q + 1, k.S_Q + 2, k.S_V, k.S_V + 1, k.S_V + 2)
"""Columns of :attr:`Trajectory.raw` holding the paper's six states (:attr:`Trajectory.states`)."""
DEFAULT_DT = 1.0 / 2400.0
"""Integration step (s): 12 steps per 200 Hz motion-capture sample, 2 per 1200 Hz SITL tick;
chosen by the step-size study in docs/model.md."""


@dataclass(frozen=True)
class Model:
    """Parameters + effects + step: everything that decides how a landing unfolds."""

    params: ModelParams
    effects: tuple[str, ...]
    user_effects: tuple[UserEffect, ...] = ()
    dt: float = DEFAULT_DT
    criteria: OutcomeCriteria = field(default_factory=OutcomeCriteria)
    implicit_springs: bool = True
    """Springs of the contacts in the implicit solve (stable at any stiffness, slightly
    dissipative); False keeps them explicit (symplectic: energy-conserving, needs a step
    well under the foot's contact period)."""

    def __post_init__(self) -> None:
        check_effect_names(self.effects)
        check_user_effects(self.user_effects)
        if not (1e-6 <= self.dt <= 5e-3):
            raise EffectError(f"dt = {self.dt} s is outside 1e-6..5e-3 s")

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def default(cls) -> Model:
        """The paper's FSA model with the shipped parameters and all their effects."""
        params = ModelParams.default()
        return cls(params, params.effects)

    @classmethod
    def from_file(cls, path: str) -> Model:
        params = ModelParams.load(path)
        return cls(params, params.effects)

    def rigid(self) -> Model:
        """The stock F450: the same vehicle with its joints locked (no shock absorbers)."""
        drop = {
            "leg_flex",
            "end_of_travel",
            "downhill_torque_growth",
            "downhill_friction_growth",
            "paper_downhill_growth",
        }
        kept = tuple(e for e in self.effects if e not in drop)
        return replace(self, effects=(*kept, "rigid_gear") if "rigid_gear" not in kept else kept)

    def with_effects(self, *names: str) -> Model:
        added = tuple(n for n in names if n not in self.effects)
        return replace(self, effects=self.effects + added)

    def without(self, *names: str) -> Model:
        for n in names:
            if n not in BUILTIN_EFFECTS and n not in [e.name for e in self.user_effects]:
                raise EffectError(f"unknown effect {n!r}")
        return replace(
            self,
            effects=tuple(e for e in self.effects if e not in names),
            user_effects=tuple(e for e in self.user_effects if e.name not in names),
        )

    def with_user_effect(self, effect: UserEffect) -> Model:
        return replace(self, user_effects=(*self.user_effects, effect))

    def with_params(self, provenance: str = "identified", **values: float) -> Model:
        """A copy with parameters set by name: built-in ones and the user effects' alike."""
        users = list(self.user_effects)
        builtin = {}
        for name, v in values.items():
            for i, e in enumerate(users):
                if name in e.parameters:
                    users[i] = e.with_values(provenance, **{name: v})
                    break
            else:
                builtin[name] = v
        params = self.params.with_values(provenance, **builtin) if builtin else self.params
        return replace(self, params=params, user_effects=tuple(users))

    def parameter(self, name: str) -> float:
        """The value of a parameter by name, built-in or of a user effect."""
        for e in self.user_effects:
            if name in e.parameters:
                return e.parameters[name].value
        return self.params[name]

    def user_parameters(self) -> dict[str, EffectParameter]:
        """Every user effect's declared parameters, by name."""
        return {n: p for e in self.user_effects for n, p in e.parameters.items()}

    # -- what the integrator sees ---------------------------------------------------------
    def flags(self) -> np.ndarray:
        fl = flags_for(self.effects)
        fl[k.F_IMPLICIT_K] = 1 if self.implicit_springs else 0
        if fl[k.F_PAPER_GROWTH]:  # eqs. 3 and 4 read the switch from their own flag's value
            fl[k.F_TAU_GROWTH] *= 2
            fl[k.F_MU_GROWTH] *= 2
        return fl

    def criteria_array(self) -> np.ndarray:
        c = self.criteria
        return np.array(
            [
                c.horizon,
                c.slide_limit,
                c.underused_fraction,
                c.flip_pitch_deg,
                c.settle_speed,
                c.settle_rate_dps,
                c.settle_time,
            ],
            dtype=np.float64,
        )

    def kernel(self):
        """The compiled integrator and this model's seam table: its user effects' compiled laws
        and parameters, or None without user effects (see :mod:`slopelander.model.seams`)."""
        return k, seam_table(self.user_effects)

    @property
    def rigid_gear(self) -> bool:
        return "rigid_gear" in self.effects


@dataclass(frozen=True)
class LandingResult:
    """The outcome of one landing and the numbers behind it."""

    outcome: Outcome
    compression_up: float
    compression_down: float
    slide: float
    final_pitch_deg: float
    min_pitch_deg: float
    settle_time: float
    t_end: float

    @classmethod
    def from_row(cls, row: np.ndarray) -> LandingResult:
        vals = {n: float(row[i]) for i, n in enumerate(RESULT_FIELDS)}
        vals["outcome"] = Outcome(int(vals["outcome"]))
        return cls(**vals)

    def pitch_margin_deg(self, flip_pitch_deg: float = 80.0, max_abs_pitch_deg: float = 0.0) -> float:
        """Degrees left between the pitch furthest from level and the flip criterion (<= 0: flipped).

        ``min_pitch_deg`` is exact (tracked every step); the nose-up side needs
        ``max_abs_pitch_deg`` from a trajectory (:attr:`Trajectory.pitch_margin_deg` passes it).
        """
        return flip_pitch_deg - max(-self.min_pitch_deg, max_abs_pitch_deg)

    def summary(self, flip_pitch_deg: float = 80.0, max_abs_pitch_deg: float = 0.0) -> str:
        settle = "never" if math.isnan(self.settle_time) else f"{self.settle_time:.2f} s"
        return (
            f"outcome: {self.outcome.label}, "
            f"{pitch_margin_text(self.pitch_margin_deg(flip_pitch_deg, max_abs_pitch_deg), flip_pitch_deg)}\n"
            f"  peak compression: uphill {100 * self.compression_up:.0f} %, "
            f"downhill {100 * self.compression_down:.0f} %\n"
            f"  slide along the slope: {self.slide:+.3f} m\n"
            f"  pitch: final {self.final_pitch_deg:+.1f} deg, most negative {self.min_pitch_deg:+.1f} deg\n"
            f"  at rest after: {settle}"
        )


def pitch_margin_text(margin_deg: float, flip_pitch_deg: float) -> str:
    """How close a landing came to flipping, in words a pilot reads."""
    if margin_deg <= 0:
        return f"pitch passed the {flip_pitch_deg:g} deg flip criterion"
    return f"closest to flipping: {margin_deg:.0f} deg margin (flip at {flip_pitch_deg:g} deg)"


@dataclass(frozen=True)
class Trajectory:
    """A simulated landing sampled like motion capture.

    ``states`` columns are the paper's six (x, z, pitch, x rate, z rate, pitch rate) in SI
    units (rad, rad/s); ``raw`` keeps every sampled state vector (kernel layout).
    """

    t: np.ndarray
    raw: np.ndarray
    conditions: LandingConditions
    model: Model
    result: LandingResult

    @property
    def states(self) -> np.ndarray:
        r = self.raw
        return np.column_stack(
            [r[:, k.S_Q], r[:, k.S_Q + 1], r[:, k.S_Q + 2], r[:, k.S_V], r[:, k.S_V + 1], r[:, k.S_V + 2]]
        )

    @property
    def leg_angles(self) -> np.ndarray:
        """Leg angles (rad) of the left (C) and right (D) legs."""
        return self.raw[:, k.S_Q + 3 : k.S_Q + 5]

    @property
    def joint_angles(self) -> np.ndarray:
        """Friction-joint angles (rad) q_E, q_F."""
        return self.raw[:, k.S_QE : k.S_QE + 2]

    @property
    def thrust(self) -> np.ndarray:
        return self.raw[:, k.S_THR : k.S_THR + 2]

    @property
    def slope_deg(self) -> float:
        return self.conditions.slope_deg

    @property
    def pitch_margin_deg(self) -> float:
        """Degrees between the largest pitch reached (either way) and the flip criterion."""
        return self.result.pitch_margin_deg(self.model.criteria.flip_pitch_deg, self._max_abs_pitch_deg)

    @property
    def _max_abs_pitch_deg(self) -> float:
        return float(np.degrees(np.abs(self.raw[:, k.S_Q + 2]).max())) if len(self.raw) else 0.0

    def effect_state(self, name: str) -> np.ndarray:
        """A user effect's state (its memory, by the name it declares) at every sample."""
        slots = memory_slots(self.model.user_effects)
        if name not in slots:
            known = ", ".join(slots) or "none"
            raise EffectError(f"no user effect of this model declares a state {name!r} (states: {known})")
        return self.raw[:, slots[name]].copy()

    @property
    def peak_foot_load(self) -> float:
        """Largest normal force on either foot during the landing (N)."""
        return float(self.raw[:, k.S_NPEAK].max()) if len(self.raw) else 0.0

    def summary(self) -> str:
        """The result's summary, with the margin to this model's flip criterion (and, for the
        stock rigid gear, its peak foot load against its structural limit)."""
        text = self.result.summary(self.model.criteria.flip_pitch_deg, self._max_abs_pitch_deg)
        if self.model.rigid_gear:
            limit = self.model.params["rigid_load_limit"]
            text += f"\n  peak foot load: {self.peak_foot_load:.0f} N (the rigid gear's limit: {limit:g} N)"
        return text

    def outline(self, i: int) -> dict[str, np.ndarray]:
        """World positions (x, z) of the vehicle's points in sample ``i``: the centre of
        mass, the rotor hubs, the leg joints and the feet (each leg's two points)."""
        M, f, pts, vel, J = k.kinematics_views(k.make_workspace())
        k.kinematics(self.model.params.as_array(), self.raw[i], M, f, pts, vel, J)
        return {
            "centre": self.raw[i, k.S_Q : k.S_Q + 2].copy(),
            "rotors": pts[4:6].copy(),
            "joints": pts[2:4].copy(),
            "feet": pts[0:2].copy(),
        }


def _prepare(model: Model | None, dt: float | None) -> tuple[Model, float]:
    model = model or Model.default()
    h = model.dt if dt is None else float(dt)
    if not (1e-6 <= h <= 5e-3):
        raise EffectError(f"dt = {h} s is outside 1e-6..5e-3 s")
    return model, h


def _cond_row(c: LandingConditions, model: Model) -> np.ndarray:
    """The integrator's row of ``c``, validated against the model's joint range: the same
    conditions are simulated again and again in a fit, so the checked row is kept per
    conditions object (frozen) and range, and handed out as a copy."""
    lo, hi = model.params.angle_min_deg, model.params.angle_max_deg
    key = (id(c), lo, hi)
    hit = _ROWS.get(key)
    if hit is None or hit[0] is not c:
        c.validate(lo, hi)
        hit = (c, conditions_array([c]).view(np.float64).copy())
        if len(_ROWS) >= _ROWS_MAX:
            _ROWS.clear()
        _ROWS[key] = hit
    return hit[1].copy()


_ROWS: dict[tuple, tuple[LandingConditions, np.ndarray]] = {}
"""Validated condition rows by (id of the conditions, joint range); the conditions are kept so
that their id is not reused."""
_ROWS_MAX = 1024


def simulate(
    conditions: LandingConditions | None = None,
    model: Model | None = None,
    *,
    dt: float | None = None,
    sample_rate: float = 200.0,
    full_horizon: bool = True,
) -> Trajectory:
    """Simulate one landing and sample it at ``sample_rate`` Hz (motion capture: 200 Hz).

    With ``full_horizon`` the recording goes on to the end of the horizon after the vehicle
    settles or once it has slid past the slide criterion (it ends at a flip); the outcome is
    the same either way.
    """
    conditions = conditions or LandingConditions()
    model, h = _prepare(model, dt)
    row = _cond_row(conditions, model)
    every = max(1, round(1.0 / (sample_rate * h)))
    n_max = int((model.criteria.horizon + conditions.thrust_off_time) / (every * h)) + 8
    rec = np.zeros((n_max, k.N_STATE))
    res = np.zeros(k.N_RESULT)
    km, sx = model.kernel()
    p, fl, crit = model.params.as_array(), model.flags(), model.criteria_array()
    args = (p, fl, row, h, crit, not full_horizon, every, rec, sx, res)
    if km.run_landing.overloads:  # compiled: no notice (``signatures`` would hash every type)
        n = call(km.run_landing, *args)
    else:
        with compiling_notice(dispatcher=km.run_landing):
            n = call(km.run_landing, *args)
    raw = rec[:n].copy()
    return Trajectory(raw[:, k.S_T].copy(), raw, conditions, model, LandingResult.from_row(res))


def simulate_batch(
    conditions: list[LandingConditions] | np.ndarray,
    model: Model | None = None,
    *,
    dt: float | None = None,
    stop_at_rest: bool = True,
) -> np.ndarray:
    """Outcomes only, for many landings at once, on every core.

    A landing stops when the vehicle is at rest (the outcome can no longer change) unless
    ``stop_at_rest`` is False, when every landing runs to the end of the horizon.

    ``conditions`` is a list of :class:`LandingConditions` or a structured array with the
    same fields (see :func:`~slopelander.model.conditions.condition_grid`). Returns a
    structured array with the fields of :data:`~slopelander.model.outcome.RESULT_FIELDS`.
    """
    model, h = _prepare(model, dt)
    arr = conditions_array(conditions)
    _validate_rows(arr, model)
    conds = arr.view(np.float64).reshape(len(arr), k.N_COND).copy()
    out = np.zeros((len(arr), k.N_RESULT))
    km, sx = model.kernel()
    if len(arr):
        args = (model.params.as_array(), model.flags(), conds, h, model.criteria_array(), stop_at_rest, sx)
        if not km.run_batch.signatures:
            # compile (or load from the cache) on an empty batch, so that the notice times the
            # compiling alone, never a long batch of landings
            with compiling_notice(dispatcher=km.run_batch):
                km.run_batch(*args[:2], conds[:0], *args[3:], out[:0])
        _run_threaded(km.run_batch, args, out)
    result = np.zeros(len(arr), dtype=RESULT_DTYPE)
    for i, n in enumerate(RESULT_FIELDS):
        result[n] = out[:, i]
    return result


BATCH_CHUNK = 4
"""Landings a thread takes at a time: they last from 0.1 to 2 s simulated, so a batch is handed
out a few at a time, not in equal shares."""


def _run_threaded(run_batch, args: tuple, out: np.ndarray) -> None:
    """Run a batch on numba's number of threads (one per core unless NUMBA_NUM_THREADS says
    otherwise): the compiled batch releases the GIL, so the threads run side by side."""
    conds = args[2]
    n = len(conds)
    threads = min(numba.get_num_threads(), max(1, n // BATCH_CHUNK))
    if threads <= 1:
        run_batch(*args, out)
        return
    chunks = iter(range(0, n, BATCH_CHUNK))
    lock = threading.Lock()

    def work() -> None:
        while True:
            with lock:
                a = next(chunks, None)
            if a is None:
                return
            b = min(a + BATCH_CHUNK, n)
            call(run_batch, *args[:2], conds[a:b], *args[3:], out[a:b])

    with ThreadPoolExecutor(threads) as pool:
        for f in [pool.submit(work) for _ in range(threads)]:
            f.result()


def _validate_rows(arr: np.ndarray, model: Model) -> None:
    """Validate a batch cheaply: check column ranges, then name the first bad row."""
    lo, hi = model.params.angle_min_deg, model.params.angle_max_deg
    ok = (
        (np.abs(arr["slope_deg"]) <= 75)
        & (arr["speed"] >= 0)
        & (arr["speed"] <= 15)
        & (arr["angle_up_deg"] >= lo)
        & (arr["angle_up_deg"] <= hi)
        & (arr["angle_down_deg"] >= lo)
        & (arr["angle_down_deg"] <= hi)
        & (arr["tau_up"] >= 0)
        & (arr["tau_down"] >= 0)
        & (arr["reverse_percent"] >= 0)
        & (arr["reverse_percent"] <= 100)
        & (arr["reverse_delay"] >= 0)
        & (arr["reverse_delay"] <= 5)
        & (
            ((arr["reverse_duration"] > 0) & (arr["reverse_duration"] <= MAX_REVERSE_DURATION))
            | (arr["reverse_duration"] == np.inf)
        )
        & (arr["reverse_ramp"] >= 0)
        & (arr["reverse_ramp"] <= MAX_REVERSE_RAMP)
        & ((arr["reverse_ramp"] == 0) | (arr["reverse_duration"] < np.inf))
    )
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        row = LandingConditions(**{n: float(arr[n][i]) for n in arr.dtype.names})
        row.validate(lo, hi)  # raises with the field's name
