"""Rotors that keep lifting as they spin down: motors cut at touchdown, the propellers' inertia
keeps them turning and pushing for a fraction of a second.

    T = spin_down_thrust * exp(-(t - t_touchdown) / 0.15 s) per rotor, along the body's z axis

A force at named points (the rotor hubs). Hidden in the truth of
tests/ident/test_diagnose_user_effects.py; the analysed model has to find it from this file.
"""

import math

import numba

from slopelander.model import layout, state
from slopelander.model.effects import EffectParameter, UserEffect

SPIN_DOWN_TIME = 0.15
"""s: time constant of a 10-inch propeller coasting down from hover speed (assumed)."""


@numba.njit
def spin_down(t, st, ctx, up, out):
    t0 = state.touchdown_time(st)
    if t0 < 0.0 or t < t0:
        return
    thrust = up[0] * math.exp(-(t - t0) / SPIN_DOWN_TIME)
    q = state.pitch(st)
    for r in range(2):
        out[layout.PT_ROTOR + r, 0] -= thrust * math.sin(q)
        out[layout.PT_ROTOR + r, 1] += thrust * math.cos(q)


EFFECTS = [
    UserEffect(
        "rotor_spin_down",
        "rotors coasting down after the motors are cut at touchdown still lift",
        point_force=spin_down,
        parameters={
            "spin_down_thrust": EffectParameter(
                2.0, "N", 0.0, 8.0, "assumed", "thrust of each rotor at touchdown", neutral=0.0
            )
        },
    )
]
