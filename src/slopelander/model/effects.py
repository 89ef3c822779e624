"""Physical effects: named, switchable pieces a model is built from.

A model is the base physics (three rigid bodies, gravity, feet on a spring-damper ground)
plus a list of effects. Built-in effects are switches of the compiled integrator. A user's
own effect is a :class:`UserEffect` in a Python file of theirs: one or more ``numba.njit``
functions plugged into the integrator's seams (the joint's torque law, the foot's friction
law, the contact's normal law, where a foot meets the ground, forces at named points,
generalised forces, a per-step update of its memory) and the parameters they read, each
declared with unit, bounds and provenance, and any states (memory) it carries::

    # my_effects.py
    import numba
    from slopelander.model import state
    from slopelander.model.effects import EffectParameter, UserEffect

    @numba.njit
    def pitch_drag(t, st, ctx, up, out):
        out[2] -= up[0] * state.pitch_rate(st)          # torque on the body's pitch

    EFFECTS = [UserEffect("pitch_drag", "air damping of pitch", force=pitch_drag,
                          parameters={"pitch_drag_coefficient":
                                      EffectParameter(0.01, "N*m*s/rad", 0.0, 1.0)})]

``up`` holds the effect's parameters in the order declared. docs/effects.md describes every
seam's arguments and has a tested example file per seam.
"""

from __future__ import annotations

import hashlib
import importlib.util
import math
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from slopelander.errors import SlopelanderError
from slopelander.model import layout as k
from slopelander.model.layout import BUILTIN_EFFECTS, Effect  # noqa: F401 - part of this API
from slopelander.model.parameters import PARAMETER_NAMES, PROVENANCES, ParameterError


class EffectError(SlopelanderError, ValueError):
    """An unknown effect, a conflicting combination, or a user effect file that cannot load."""


_EXCLUSIVE = (("foot_stiction", "regularised_friction"),)
_RIGID_EXCLUDES = ("leg_flex", "end_of_travel", "downhill_torque_growth")


def check_effect_names(names: Iterable[object], source: str | None = None) -> None:
    """Raise :class:`EffectError` for an unknown name or a combination that cannot be."""
    where = f"{source}: " if source else ""
    names = list(names)
    for n in names:
        if n not in BUILTIN_EFFECTS:
            raise EffectError(
                f"{where}effects: unknown effect {n!r}; built-in effects are "
                f"{', '.join(BUILTIN_EFFECTS)} (a user effect is loaded from its file)"
            )
    if len(set(names)) != len(names):
        raise EffectError(f"{where}effects: an effect is listed twice")
    for a, b in _EXCLUSIVE:
        if a in names and b in names:
            raise EffectError(f"{where}effects: {a!r} and {b!r} are alternatives; choose one")
    if "paper_downhill_growth" in names and not {"downhill_torque_growth", "downhill_friction_growth"} & set(
        names
    ):
        raise EffectError(
            f"{where}effects: 'paper_downhill_growth' says which leg eqs. 3 and 4 act on; add "
            "'downhill_torque_growth' or 'downhill_friction_growth' (or both)"
        )
    if "rigid_gear" in names:
        clash = [n for n in _RIGID_EXCLUDES if n in names]
        if clash:
            raise EffectError(
                f"{where}effects: 'rigid_gear' locks the joints, so {', '.join(clash)} cannot apply"
            )


def flags_for(names: Sequence[str]) -> np.ndarray:
    check_effect_names(names)
    fl = np.zeros(k.N_FLAGS, dtype=np.int64)
    for n in names:
        fl[BUILTIN_EFFECTS[n].flag] = 1
    return fl


SEAM_NAMES: tuple[str, ...] = tuple(k.SEAMS)


@dataclass(frozen=True)
class EffectParameter:
    """A user effect's parameter, declared like a built-in one: value, unit, bounds (the
    default search bounds of a fit), provenance, and optionally the value at which the effect
    does nothing (a fit of a candidate effect starts there)."""

    value: float
    unit: str
    low: float = -math.inf
    high: float = math.inf
    provenance: str = "assumed"
    note: str = ""
    neutral: float | None = None

    @property
    def bounded(self) -> bool:
        return math.isfinite(self.low) and math.isfinite(self.high)


def _as_parameter(effect: str, name: str, spec: object) -> EffectParameter:
    if isinstance(spec, EffectParameter):
        p = spec
    elif isinstance(spec, tuple) and 2 <= len(spec) <= 6:
        try:
            p = EffectParameter(float(spec[0]), *spec[1:])  # type: ignore[arg-type]
        except (TypeError, ValueError):
            p = None  # type: ignore[assignment]
        if p is None:
            raise EffectError(f"user effect {effect!r}: parameter {name!r}: {spec[0]!r} is not a number")
    else:
        raise EffectError(
            f"user effect {effect!r}: parameter {name!r} must be EffectParameter(value, unit, low, "
            "high, ...) or a tuple (value, unit[, low, high[, provenance[, note]]])"
        )
    where = f"user effect {effect!r}"
    if not name.isidentifier():
        raise EffectError(f"{where}: parameter name {name!r} must be an identifier")
    if name in PARAMETER_NAMES:
        raise EffectError(f"{where}: parameter {name!r} has the name of a built-in parameter")
    try:
        value, low, high = float(p.value), float(p.low), float(p.high)
    except (TypeError, ValueError):
        raise EffectError(f"{where}: parameter {name!r}: value and bounds must be numbers") from None
    if not isinstance(p.unit, str):
        raise EffectError(f"{where}: parameter {name!r}: unit must be a string")
    if p.provenance not in PROVENANCES:
        raise ParameterError(
            name, f"provenance must be one of {', '.join(PROVENANCES)}, got '{p.provenance}'", where
        )
    if math.isnan(low) or math.isnan(high) or low > high:
        raise ParameterError(name, f"bounds {low}..{high} must have low <= high", where)
    if not math.isfinite(value):
        raise ParameterError(name, "must be finite", where)
    if not low <= value <= high:
        raise ParameterError(name, f"{value} {p.unit} is outside {low}..{high}", where)
    if p.neutral is not None and not low <= float(p.neutral) <= high:
        raise ParameterError(name, f"neutral value {p.neutral} is outside {low}..{high}", where)
    return EffectParameter(
        value, p.unit, low, high, p.provenance, str(p.note), None if p.neutral is None else float(p.neutral)
    )


@dataclass(frozen=True)
class EffectState:
    """A user effect's memory: a number the integrator carries in its state vector from step
    to step (saved with the state, restored when a step is redone), starting at ``value`` in
    every landing. The effect's functions read it with ``state.memory(st, ctx, i)`` and write it
    with ``state.set_memory(st, ctx, i, value)``, ``i`` in the order declared."""

    value: float
    unit: str
    note: str = ""


def _as_state(effect: str, name: str, spec: object) -> EffectState:
    where = f"user effect {effect!r}: state {name!r}"
    if isinstance(spec, tuple) and 2 <= len(spec) <= 3:
        spec = EffectState(*spec)  # type: ignore[arg-type]
    if not isinstance(spec, EffectState):
        raise EffectError(f"{where} must be EffectState(value, unit[, note]) or a tuple (value, unit)")
    if not name.isidentifier():
        raise EffectError(f"user effect {effect!r}: state name {name!r} must be an identifier")
    if name in PARAMETER_NAMES:
        raise EffectError(f"{where} has the name of a built-in parameter")
    try:
        value = float(spec.value)
    except (TypeError, ValueError):
        raise EffectError(f"{where}: initial value {spec.value!r} is not a number") from None
    if not math.isfinite(value):
        raise EffectError(f"{where}: initial value must be finite")
    if not isinstance(spec.unit, str):
        raise EffectError(f"{where}: unit must be a string")
    return EffectState(value, spec.unit, str(spec.note))


@dataclass(frozen=True)
class UserEffect:
    """An effect written by a user: compiled functions at one or more seams, and parameters.

    ``parameters`` maps each parameter name to an :class:`EffectParameter` (a tuple
    ``(value, unit[, low, high[, provenance[, note]]])`` is accepted too).
    """

    name: str
    description: str
    force: Callable | None = None
    parameters: dict[str, EffectParameter] = field(default_factory=dict)
    point_force: Callable | None = None
    joint_torque: Callable | None = None
    foot_friction: Callable | None = None
    normal_force: Callable | None = None
    contact_geometry: Callable | None = None
    update: Callable | None = None
    states: dict[str, EffectState] = field(default_factory=dict)
    """Memory the integrator carries for this effect (name -> :class:`EffectState`)."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise EffectError(f"user effect name {self.name!r} must be an identifier")
        if self.name in BUILTIN_EFFECTS:
            raise EffectError(f"user effect {self.name!r} has the name of a built-in effect")
        if not self.seams():
            raise EffectError(
                f"user effect {self.name!r} plugs into no seam: give one of {', '.join(SEAM_NAMES)}"
            )
        for seam, fn in self.seams().items():
            if not hasattr(fn, "py_func"):
                raise EffectError(
                    f"user effect {self.name!r}: {seam} must be compiled with numba.njit "
                    "(it runs inside the integrator)"
                )
        if not isinstance(self.parameters, dict):
            raise EffectError(f"user effect {self.name!r}: parameters must be a dict name -> EffectParameter")
        params = {str(n): _as_parameter(self.name, str(n), spec) for n, spec in self.parameters.items()}
        object.__setattr__(self, "parameters", params)
        if not isinstance(self.states, dict):
            raise EffectError(f"user effect {self.name!r}: states must be a dict name -> EffectState")
        states = {str(n): _as_state(self.name, str(n), spec) for n, spec in self.states.items()}
        clash = sorted(set(states) & set(params))
        if clash:
            raise EffectError(f"user effect {self.name!r}: {clash[0]!r} is both a parameter and a state")
        if len(states) > k.N_MEMORY:
            raise EffectError(
                f"user effect {self.name!r} declares {len(states)} states; a model holds {k.N_MEMORY}"
            )
        object.__setattr__(self, "states", states)

    def seams(self) -> dict[str, Callable]:
        """The seams this effect plugs into, and its function at each."""
        return {s: getattr(self, s) for s in SEAM_NAMES if getattr(self, s) is not None}

    def values(self) -> np.ndarray:
        return np.array([p.value for p in self.parameters.values()], dtype=np.float64)

    def state_values(self) -> np.ndarray:
        """The states' initial values, in the order declared."""
        return np.array([s.value for s in self.states.values()], dtype=np.float64)

    def with_values(self, provenance: str = "identified", **changes: float) -> UserEffect:
        """A copy with some parameter values replaced (checked against their bounds)."""
        params = dict(self.parameters)
        for n, v in changes.items():
            if n not in params:
                raise EffectError(f"user effect {self.name!r} has no parameter {n!r}")
            params[n] = replace(params[n], value=float(v), provenance=provenance)
        return replace(self, parameters=params)

    def record(self) -> dict[str, object]:
        """What a map or table writes about this effect (its parameters like the built-ins')."""
        seams = self.seams()
        fn = next(iter(seams.values())).py_func
        file = getattr(sys.modules.get(fn.__module__), "__file__", None)
        return {
            "description": self.description,
            "seams": list(seams),
            **({"file": str(file)} if file else {}),
            "parameters": {
                n: {
                    "value": p.value,
                    "unit": p.unit,
                    "low": p.low,
                    "high": p.high,
                    "provenance": p.provenance,
                    **({"note": p.note} if p.note else {}),
                }
                for n, p in self.parameters.items()
            },
            **(
                {
                    "states": {
                        n: {"initial": s.value, "unit": s.unit, **({"note": s.note} if s.note else {})}
                        for n, s in self.states.items()
                    }
                }
                if self.states
                else {}
            ),
        }


def load_effects(path: str | Path) -> list[UserEffect]:
    """Load the user effects defined in a Python file (its ``EFFECTS`` list, or every
    module-level :class:`UserEffect`)."""
    path = Path(path)
    if not path.is_file():
        raise EffectError(f"{path}: no such effect file")
    # named by content: the compiled integrator that calls it is cached under this name
    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    mod_name = f"slopelander_user_effects_{digest}"
    if mod_name in sys.modules:  # the same file loaded twice: the same functions
        module = sys.modules[mod_name]
    else:
        spec = importlib.util.spec_from_file_location(mod_name, path)
        if spec is None or spec.loader is None:
            raise EffectError(f"{path}: not a Python file")
        module = importlib.util.module_from_spec(spec)
        sys.modules[mod_name] = module
        try:
            spec.loader.exec_module(module)
        except SlopelanderError as exc:
            del sys.modules[mod_name]
            raise EffectError(f"{path}: {exc}") from None
        except Exception as exc:  # the user's file: report, do not crash
            del sys.modules[mod_name]
            raise EffectError(f"{path}: failed to load: {type(exc).__name__}: {exc}") from exc
    found = getattr(module, "EFFECTS", None)
    if found is None:
        found = [v for v in vars(module).values() if isinstance(v, UserEffect)]
    if not found or not all(isinstance(e, UserEffect) for e in found):
        raise EffectError(f"{path}: defines no UserEffect (set EFFECTS = [UserEffect(...)])")
    return list(found)


def check_user_effects(effects: Sequence[UserEffect]) -> None:
    """Names and parameters unique across a model's user effects; one normal-force law."""
    names = [e.name for e in effects]
    if len(set(names)) != len(names):
        raise EffectError("a user effect is listed twice")
    seen: dict[str, str] = {}
    for e in effects:
        for n in e.parameters:
            if n in seen:
                raise EffectError(f"user effects {seen[n]!r} and {e.name!r} both declare parameter {n!r}")
            seen[n] = e.name
    states: dict[str, str] = {}
    for e in effects:
        for n in e.states:
            if n in seen or n in states:
                other = seen.get(n) or states[n]
                raise EffectError(f"user effects {other!r} and {e.name!r} both declare {n!r}")
            states[n] = e.name
    if len(states) > k.N_MEMORY:
        raise EffectError(
            f"the user effects declare {len(states)} states together; a model holds {k.N_MEMORY}"
        )
    for seam, what in (("normal_force", "normal-force law"), ("contact_geometry", "contact geometry")):
        laws = [e.name for e in effects if getattr(e, seam) is not None]
        if len(laws) > 1:
            names = ", ".join(map(repr, laws))
            raise EffectError(f"user effects {names} each set the {what}; keep one")


def memory_values(effects: Sequence[UserEffect]) -> np.ndarray:
    """The user effects' states' initial values in one array, in the order the integrator
    holds them (from ``layout.S_MEM``)."""
    return np.concatenate([e.state_values() for e in effects] + [np.zeros(0)])


def memory_slots(effects: Sequence[UserEffect]) -> dict[str, int]:
    """Each user effect state's index in the state vector, by name."""
    out: dict[str, int] = {}
    for e in effects:
        for n in e.states:
            out[n] = k.S_MEM + len(out)
    return out


def user_parameter_values(effects: Sequence[UserEffect]) -> np.ndarray:
    """The user effects' parameters in one array, in the order their functions read them."""
    return np.concatenate([e.values() for e in effects] + [np.zeros(1)])
