"""Velocity-weakening (Stribeck) foot friction: a slow foot grips harder than a fast one.

Seam: the foot's friction coefficient. The integrator calls ``foot_friction`` every step for
each foot in contact with its slip speed along the surface (m/s, downhill-positive), its normal
force (N) and the coefficient the built-in model would use (mu_k, grown by eq. 4 on the
downhill foot if that effect is on); the value returned is the sliding friction coefficient of
that step. (A stuck foot still holds up to friction_static, the built-in stiction law.)

    mu = mu_builtin * (1 + stribeck_boost * exp(-|v| / STRIBECK_SPEED))
"""

import math

import numba

from slopelander.model.effects import EffectParameter, UserEffect

STRIBECK_SPEED = 0.2  # m/s: below this the grip rises toward mu_k * (1 + boost)


@numba.njit
def stribeck_mu(t, st, ctx, up, leg, slip_speed, normal_force, mu):
    boost = up[0]
    return mu * (1.0 + boost * math.exp(-abs(slip_speed) / STRIBECK_SPEED))


EFFECTS = [
    UserEffect(
        "stribeck_feet",
        "foot friction rises as the slip slows (velocity weakening)",
        foot_friction=stribeck_mu,
        parameters={
            "stribeck_boost": EffectParameter(
                0.5, "1", 0.0, 2.0, "assumed", "grip at rest over grip sliding, minus one", neutral=0.0
            )
        },
    )
]
