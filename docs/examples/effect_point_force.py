"""Quadratic air drag on the body, applied at its centre of mass.

Seam: forces at named points. The integrator calls ``point_force`` every step with an array
``out`` of one row per named point (``layout.PT_FOOT + leg``, ``PT_JOINT + leg``,
``PT_ROTOR + rotor``, ``PT_CENTRE``) and two columns (world x, z force in N); what is added
there is mapped onto the model's coordinates through the points' Jacobians. The work these
forces take out is booked as ``user_effects`` in the energy bookkeeping.

    F = -drag_coefficient |v| v
"""

import math

import numba

from slopelander.model import layout, state
from slopelander.model.effects import EffectParameter, UserEffect


@numba.njit
def body_drag(t, st, ctx, up, out):
    c = up[0]
    vx = state.vx(st)
    vz = state.vz(st)
    speed = math.sqrt(vx * vx + vz * vz)
    out[layout.PT_CENTRE, 0] -= c * speed * vx
    out[layout.PT_CENTRE, 1] -= c * speed * vz


EFFECTS = [
    UserEffect(
        "body_drag",
        "quadratic air drag on the body, 0.5 rho Cd A |v| v",
        point_force=body_drag,
        parameters={
            "drag_coefficient": EffectParameter(0.05, "kg/m", 0.0, 5.0, note="rho Cd A / 2", neutral=0.0)
        },
    )
]
