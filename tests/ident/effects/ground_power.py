"""A ground whose spring grows as a power of the penetration, built on the model's own ground.

Seam: the contact's normal force law. It reads the model's ground stiffness and damping at the
contact point (``state.ground_stiffness(ctx)``, ``state.ground_damping(ctx)``), so at its
neutral exponent 1 it is the built-in linear spring-damper, and a candidate built this way is
nested in the base model:

    N = k d0 (d / d0)^e + b d',   d0 = 1 mm,   clipped at 0 (the ground never pulls)
"""

import numba

from slopelander.model import state
from slopelander.model.effects import EffectParameter, UserEffect

D0 = 1e-3


@numba.njit
def ground_power(t, st, ctx, up, point, depth, rate):
    k = state.ground_stiffness(ctx)
    b = state.ground_damping(ctx)
    e = up[0]
    spring = k * D0 * (depth / D0) ** e
    force = spring + b * rate
    if force <= 0.0:
        return 0.0, 0.0, 0.0
    return force, e * spring / depth, b


EFFECTS = [
    UserEffect(
        "ground_power",
        "the model's ground spring raised to a power of the penetration (1 = linear)",
        normal_force=ground_power,
        parameters={"ground_exponent": EffectParameter(1.0, "1", 0.5, 2.0, "assumed", neutral=1.0)},
    )
]
