"""Physical effects: named, switchable pieces a model is built from.

A model is the base physics (three rigid bodies, gravity, feet on a spring-damper ground)
plus a list of effects. Built-in effects are switches of the compiled integrator; a user's
own effect is a :class:`UserEffect` in a Python file of theirs, whose ``force`` function
(compiled with ``numba.njit``) adds generalised forces every step::

    # my_effects.py
    import numba
    from slopelander.model.effects import UserEffect
    from slopelander.model import kernel as k

    @numba.njit
    def pitch_drag(t, st, ctx, up, out):
        out[2] -= up[0] * st[k.S_V + 2]          # torque on the body's pitch

    EFFECTS = [UserEffect("pitch_drag", "air damping of pitch", pitch_drag,
                          {"pitch_drag_coefficient": (0.01, "N*m*s/rad")})]

``out`` holds generalised forces on (x, z, pitch, q_C, q_D); ``st`` is the state vector
laid out as in :mod:`slopelander.model.kernel`; ``up`` holds the effect's parameters in the
order declared.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slopelander.errors import SlopelanderError
from slopelander.model import kernel as k


class EffectError(SlopelanderError, ValueError):
    """An unknown effect, a conflicting combination, or a user effect file that cannot load."""


@dataclass(frozen=True)
class Effect:
    name: str
    description: str
    parameters: tuple[str, ...]
    flag: int


BUILTIN_EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "leg_flex",
            "legs bend on a torsional spring-damper in series with the friction joint (eq. 2)",
            ("flex_stiffness", "flex_damping"),
            k.F_FLEX,
        ),
        Effect(
            "end_of_travel",
            "spring-damper stop within eot_zone_deg of the joint limit",
            ("eot_zone_deg", "eot_stiffness", "eot_damping"),
            k.F_EOT,
        ),
        Effect(
            "downhill_torque_growth",
            "downhill joint torque grows with its foot's friction force (eq. 3)",
            ("factor_tau",),
            k.F_TAU_GROWTH,
        ),
        Effect(
            "downhill_friction_growth",
            "downhill foot friction grows with its joint's downhill speed (eq. 4)",
            ("factor_mu",),
            k.F_MU_GROWTH,
        ),
        Effect(
            "foot_stiction",
            "feet stick (tangential spring-damper) until |F_t| > mu_s N, then slide with mu_k",
            ("friction_static", "stiction_stiffness", "stiction_damping"),
            k.F_STICTION,
        ),
        Effect(
            "regularised_friction",
            "feet follow mu_k N tanh(v / v_s): smooth, but creeps on slopes (comparison only)",
            ("friction_smoothing_speed",),
            k.F_REGULARISED,
        ),
        Effect(
            "rotors",
            "rotor thrust with first-order speed dynamics, weaker in reverse",
            ("rotor_thrust_max", "rotor_reverse_ratio", "rotor_time_constant"),
            k.F_ROTORS,
        ),
        Effect(
            "rotor_reversal_delay",
            "a rotor changing direction stops and restarts: no thrust for the delay",
            ("rotor_reversal_delay",),
            k.F_REV_DELAY,
        ),
        Effect(
            "rigid_gear",
            "stock rigid landing gear: joints locked at their set angle, same geometry",
            (),
            k.F_RIGID,
        ),
    )
}

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


@dataclass(frozen=True)
class UserEffect:
    """An effect written by a user: a compiled generalised-force function and its parameters.

    ``parameters`` maps each parameter name to ``(value, unit)``.
    """

    name: str
    description: str
    force: Callable
    parameters: dict[str, tuple[float, str]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise EffectError(f"user effect name {self.name!r} must be an identifier")
        if self.name in BUILTIN_EFFECTS:
            raise EffectError(f"user effect {self.name!r} has the name of a built-in effect")
        if not hasattr(self.force, "py_func"):
            raise EffectError(
                f"user effect {self.name!r}: force must be compiled with numba.njit "
                "(it runs inside the integrator)"
            )
        for pname, spec in self.parameters.items():
            if not (isinstance(spec, tuple) and len(spec) == 2):
                raise EffectError(f"user effect {self.name!r}: parameter {pname!r} must be (value, unit)")

    def values(self) -> np.ndarray:
        return np.array([float(v) for v, _ in self.parameters.values()], dtype=np.float64)

    def with_values(self, **changes: float) -> UserEffect:
        params = dict(self.parameters)
        for n, v in changes.items():
            if n not in params:
                raise EffectError(f"user effect {self.name!r} has no parameter {n!r}")
            params[n] = (float(v), params[n][1])
        return UserEffect(self.name, self.description, self.force, params)


def load_effects(path: str | Path) -> list[UserEffect]:
    """Load the user effects defined in a Python file (its ``EFFECTS`` list, or every
    module-level :class:`UserEffect`)."""
    path = Path(path)
    if not path.is_file():
        raise EffectError(f"{path}: no such effect file")
    # named by content: the compiled integrator that calls it is cached under this name
    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    mod_name = f"slopelander_user_effects_{digest}"
    spec = importlib.util.spec_from_file_location(mod_name, path)
    if spec is None or spec.loader is None:
        raise EffectError(f"{path}: not a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module
    try:
        spec.loader.exec_module(module)
    except SlopelanderError:
        raise
    except Exception as exc:  # the user's file: report, do not crash
        raise EffectError(f"{path}: failed to load: {type(exc).__name__}: {exc}") from exc
    found = getattr(module, "EFFECTS", None)
    if found is None:
        found = [v for v in vars(module).values() if isinstance(v, UserEffect)]
    if not found or not all(isinstance(e, UserEffect) for e in found):
        raise EffectError(f"{path}: defines no UserEffect (set EFFECTS = [UserEffect(...)])")
    return list(found)


def user_parameter_values(effects: Sequence[UserEffect]) -> np.ndarray:
    """The user effects' parameters in one array, in the order their forces read them."""
    return np.concatenate([e.values() for e in effects] + [np.zeros(1)])
