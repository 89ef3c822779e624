"""Hunt-Crossley ground contact: a Hertzian spring whose damping grows with the penetration.

Seam: the contact's normal force law. The integrator calls ``normal_force`` every step for each
contact point pressed into the ground, with its penetration depth (m, > 0) and its rate
(m/s, > 0 while pressing in). It returns the normal force (N, pushing out) and its derivatives
with respect to depth and rate: the integrator treats the contact implicitly with them, so a
stiff law stays stable at the model's step. (Its net work is booked under ``ground_damper``
in the energy bookkeeping: no potential is known for a user's law.)

    N = k d^1.5 (1 + 1.5 alpha d'),  clipped at 0 (the ground never pulls)
"""

import math

import numba

from slopelander.model.effects import EffectParameter, UserEffect


@numba.njit
def hunt_crossley(t, st, ctx, up, point, depth, rate):
    k = up[0]
    alpha = up[1]
    root = math.sqrt(depth)
    spring = k * depth * root
    damp = 1.0 + 1.5 * alpha * rate
    force = spring * damp
    if force <= 0.0:
        return 0.0, 0.0, 0.0
    return force, 1.5 * k * root * damp, spring * 1.5 * alpha


EFFECTS = [
    UserEffect(
        "hunt_crossley_ground",
        "Hertzian ground contact with penetration-proportional damping (Hunt and Crossley 1975)",
        normal_force=hunt_crossley,
        parameters={
            "hc_stiffness": EffectParameter(2.0e6, "N/m^1.5", 1e4, 1e8, "assumed", "k of N = k d^1.5"),
            "hc_damping": EffectParameter(0.5, "s/m", 0.0, 5.0, "assumed", "alpha: e ~ 1 - alpha v"),
        },
    )
]
