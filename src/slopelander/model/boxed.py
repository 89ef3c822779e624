"""The stepper's seam table in one compiled object, passed by reference on every step.

A call into the integrator unboxes its arguments; for the seam table (twenty first-class
functions) that costs about 0.2 ms a call, several times the step itself, and the simulated
vehicle steps 1,200 times per simulated second. Held in a numba StructRef the table crosses into
compiled code as one pointer (a few us), and ``advance_boxed`` rebuilds the tuple inside compiled
code, where it costs nothing. (A jitclass would do the same, but its type is new in every process,
so the functions taking it would be compiled again on every start.)
"""

from __future__ import annotations

import numba
from numba import njit, types
from numba.experimental import structref

from slopelander.model import kernel as k
from slopelander.model.seams import _laws_and_slots

_LAWS = numba.typeof(_laws_and_slots([])[0])  # the same type for every table: one per seam's signature


@structref.register
class SeamBoxType(types.StructRef):
    """numba's type of a boxed seam table."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(t)) for name, t in fields)


class SeamBox(structref.StructRefProxy):
    """``(laws, slots, up)`` of :func:`slopelander.model.seams.seam_table`, held by reference."""


structref.define_proxy(SeamBox, SeamBoxType, ["laws", "slots", "up"])
_BOX = SeamBoxType([("laws", _LAWS), ("slots", types.int64[:, ::1]), ("up", types.float64[::1])])


@njit(cache=True)
def _new_box(laws, slots, up):  # pragma: no cover - compiled
    b = structref.new(_BOX)
    b.laws = laws
    b.slots = slots
    b.up = up
    return b


def box(sx: tuple) -> SeamBox:
    """The boxed form of a seam table (of a model with user effects; one without passes None
    itself, which crosses into compiled code for nothing)."""
    laws, slots, up = sx
    return _new_box(laws, slots, up)


@njit(cache=True)
def advance_boxed(p, fl, ctx, st, h, n, u0, u1, ws, bx):  # pragma: no cover - compiled
    """:func:`slopelander.model.kernel.advance` with the seam table boxed."""
    k.advance(p, fl, ctx, st, h, n, u0, u1, ws, (bx.laws, bx.slots, bx.up))
