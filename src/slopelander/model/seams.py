"""The integrator's seams: where an effect's compiled law enters a step.

Each seam (``layout.SEAMS``) has one function type. The integrator takes, besides its arrays,
one more argument: the *seam table* ``(laws, slots, up)``, where ``laws`` holds per seam a
tuple of :data:`SLOTS` first-class compiled functions of that type, ``slots`` (int array,
one row per seam, ``layout.SEAM_ROW`` wide) says how many are in use, which slice of ``up``
(the user parameters) each reads and where its effect's memory starts in the state; its last
row (``layout.MEMORY_ROW``) says how many memory slots the effects use and where their initial
values sit in ``up`` (after the parameters). The integrator calls a seam's laws in turn after
the built-in law of that stage.

Because the functions are typed by their signature alone (numba's first-class function
type), one compiled integrator serves every model with user effects: a user's, and every
candidate effect of a diagnosis. Its code is compiled once and cached on disk; a user's law
is compiled on its own (small, seconds) and handed over as a function pointer. A model without
user effects passes None instead of a table, and runs the integrator compiled for None, in
which no seam is looked at and no law is called (calls through first-class functions cost the
built-in model's step its speed).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
from numba import njit, types
from numba.core.errors import NumbaExperimentalFeatureWarning
from numba.core.types import WrapperAddressProtocol
from numba.experimental.function_type import _get_wrapper_address

from slopelander.model.effects import EffectError, UserEffect, check_user_effects
from slopelander.model.layout import MEMORY_ROW, SEAM_INDEX, SEAM_ROW, SEAM_SLOTS, SEAMS
from slopelander.model.usercode import check_types

SLOTS = SEAM_SLOTS
"""Laws one seam can take in one model (more is an :class:`EffectError`)."""

# first-class functions are marked experimental by numba; the integrator relies on them on purpose
warnings.filterwarnings("ignore", category=NumbaExperimentalFeatureWarning)

_A1 = types.Array(types.float64, 1, "C")
_A2 = types.Array(types.float64, 2, "C")
_F, _I = types.float64, types.int64

SIGNATURES = {
    "force": types.none(_F, _A1, _A1, _A1, _A1),
    "point_force": types.none(_F, _A1, _A1, _A1, _A2),
    "joint_torque": _F(_F, _A1, _A1, _A1, _I, _F, _F, _F),
    "foot_friction": _F(_F, _A1, _A1, _A1, _I, _F, _F, _F),
    "normal_force": types.UniTuple(_F, 3)(_F, _A1, _A1, _A1, _I, _F, _F),
    "contact_geometry": types.UniTuple(_F, 2)(_F, _A1, _A1, _A1, _I, _F),
    "update": types.none(_F, _A1, _A1, _A1, _F),
}
assert tuple(SIGNATURES) == tuple(SEAMS) == tuple(SEAM_INDEX)


@njit(cache=True)
def no_force(t, st, ctx, up, out):  # pragma: no cover - compiled
    """An empty slot of a force seam (never called: the slot count excludes it)."""
    return


@njit(cache=True)
def no_law(t, st, ctx, up, i, a, b, value):  # pragma: no cover - compiled
    """An empty slot of a law seam: the value it is given."""
    return value


@njit(cache=True)
def no_normal_law(t, st, ctx, up, point, depth, rate):  # pragma: no cover - compiled
    """An empty normal-law slot (never called: the built-in spring-damper is used)."""
    return 0.0, 0.0, 0.0


@njit(cache=True)
def no_geometry(t, st, ctx, up, leg, angle):  # pragma: no cover - compiled
    """An empty contact-geometry slot (never called: the foot touches at its tip)."""
    return 0.0, 0.0


@njit(cache=True)
def no_update(t, st, ctx, up, h):  # pragma: no cover - compiled
    """An empty update slot (never called: the slot count excludes it)."""
    return


_EMPTY = {
    "force": no_force,
    "point_force": no_force,
    "joint_torque": no_law,
    "foot_friction": no_law,
    "normal_force": no_normal_law,
    "contact_geometry": no_geometry,
    "update": no_update,
}


class Law(WrapperAddressProtocol):
    """A compiled function plugged into a seam: numba sees it as a function of the seam's
    type (its address is taken once compiled), never as that particular function."""

    def __init__(self, fn, seam: str) -> None:
        self.fn = fn
        self.seam = seam
        self._sig = SIGNATURES[seam]
        self._addr: int | None = None
        self.source = fn

    def __wrapper_address__(self) -> int:
        if self._addr is None:
            self._addr = _get_wrapper_address(self.fn, self._sig)
        return self._addr

    def signature(self):
        return self._sig


_laws: dict[tuple[int, str], Law] = {}


def law(fn, seam: str) -> Law:
    """The seam law of a compiled function (one per function and seam, kept for reuse: its
    adapter and its address are made once per process)."""
    key = (id(fn), seam)
    got = _laws.get(key)
    if got is None or got.source is not fn:
        got = Law(fn if fn is _EMPTY[seam] else _adapted(fn, seam), seam)
        got.source = fn
        _laws[key] = got
    return got


def _adapted(fn, seam: str):
    """``fn`` if it already returns the seam's type, else a compiled adapter that converts
    (a law returning an int, a force hook returning something)."""
    sig = SIGNATURES[seam]
    got = next(s.return_type for s in fn.nopython_signatures if tuple(s.args) == tuple(sig.args))
    if got == sig.return_type:
        return fn
    if seam in ("force", "point_force"):

        @njit
        def hook(t, st, ctx, up, out):  # pragma: no cover - compiled
            fn(t, st, ctx, up, out)

        return hook
    if seam == "update":

        @njit
        def update(t, st, ctx, up, h):  # pragma: no cover - compiled
            fn(t, st, ctx, up, h)

        return update
    if seam == "contact_geometry":

        @njit
        def geometry(t, st, ctx, up, leg, angle):  # pragma: no cover - compiled
            a, b = fn(t, st, ctx, up, leg, angle)
            return float(a), float(b)

        return geometry
    if seam == "normal_force":

        @njit
        def normal(t, st, ctx, up, point, depth, rate):  # pragma: no cover - compiled
            n, k, b = fn(t, st, ctx, up, point, depth, rate)
            return float(n), float(k), float(b)

        return normal

    @njit
    def scalar(t, st, ctx, up, i, a, b, value):  # pragma: no cover - compiled
        return float(fn(t, st, ctx, up, i, a, b, value))

    return scalar


def seam_table(effects: Sequence[UserEffect]) -> tuple | None:
    """The integrator's seam argument for these user effects: None for none (numba compiles
    the integrator for a model without user effects on its own, with no seam in it).

    The laws and slots of a tuple of effects are worked out once (a fit simulates the same
    model's effects thousands of times, and typing their laws is the dearest part); the
    parameters are read afresh on every call, and the arrays are the caller's own."""
    if not effects:
        return None
    if isinstance(effects, tuple):
        hit = _TABLES.get(id(effects))
        if hit is None or hit[0] is not effects:
            hit = (effects, *_laws_and_slots(effects))
            if len(_TABLES) >= _TABLES_MAX:
                _TABLES.clear()
            _TABLES[id(effects)] = hit
        laws, slots = hit[1], hit[2].copy()
    else:
        laws, slots = _laws_and_slots(effects)
    up = np.concatenate([e.values() for e in effects] + [e.state_values() for e in effects] + [np.zeros(1)])
    return laws, slots, up


_TABLES: dict[int, tuple] = {}
"""Laws and slots of the effect tuples seen, by identity (the tuple is kept so that its id is
not reused); user effects are frozen, so a tuple's laws and slots never change."""
_TABLES_MAX = 256


def _laws_and_slots(effects: Sequence[UserEffect]) -> tuple[tuple, np.ndarray]:
    check_user_effects(effects)
    slots = np.zeros((len(SEAMS) + 1, SEAM_ROW), dtype=np.int64)
    funcs: dict[str, list] = {s: [] for s in SEAMS}
    offset = 0
    memory = 0
    for e in effects:
        n = len(e.parameters)
        seams = e.seams()
        if seams:
            check_types(e)
        for seam, fn in seams.items():
            row = slots[SEAM_INDEX[seam]]
            used = int(row[0])
            if used >= SLOTS:
                raise EffectError(
                    f"user effect {e.name!r}: more than {SLOTS} effects plug into the {seam} seam; "
                    "combine some into one"
                )
            row[1 + 3 * used] = offset
            row[2 + 3 * used] = n
            row[3 + 3 * used] = memory
            row[0] = used + 1
            funcs[seam].append(law(fn, seam))
        offset += n
        memory += len(e.states)
    # the memory row: how many states, and where their initial values follow the parameters in up
    slots[MEMORY_ROW, 0] = memory
    slots[MEMORY_ROW, 1] = offset
    laws = tuple(tuple(funcs[s] + [law(_EMPTY[s], s)] * (SLOTS - len(funcs[s]))) for s in SEAMS)
    for row in laws:
        for one in row:
            one.__wrapper_address__()  # compiled now, in this process (workers forked later inherit it)
    return laws, slots
