"""Round foot pads: the foot touches the ground on a ball, not at the leg's tip.

Seam: the contact's geometry. The integrator asks ``contact_geometry`` every step, for each
leg, where on the foot the ground is met, given the leg's angle from the surface's inward
normal (rad; positive when the foot lies toward +x along the surface). It returns how far
beyond the tip that point reaches toward the surface (m) and how far it lies along the surface
(m, +x side). The point moves with the leg, so depth, slip, friction and the normal force all
act there, and a pad starts its contact as soon as its surface meets the ground.

A ball of radius ``pad_radius`` whose centre sits ``pad_inset`` radii back up the leg from its
tip (0: centred on the tip; 1: its bottom at the tip when the leg is normal to the surface)
meets a plane at its lowest point, centre - r n:

    reach = r (1 - inset cos a),  along = -inset r sin a

At ``pad_radius = 0`` the foot touches at its tip again: a landing is the base model's to the
last bit (tests/model/test_effect_examples.py).
"""

import math

import numba

from slopelander.model.effects import EffectParameter, UserEffect


@numba.njit
def round_pad(t, st, ctx, up, leg, angle):
    r = up[0]
    inset = up[1]
    return r * (1.0 - inset * math.cos(angle)), -inset * r * math.sin(angle)


EFFECTS = [
    UserEffect(
        "round_foot_pads",
        "the feet meet the ground on round pads, whose lowest point touches first",
        contact_geometry=round_pad,
        parameters={
            "pad_radius": EffectParameter(0.02, "m", 0.0, 0.1, "assumed", "radius of the ball", neutral=0.0),
            "pad_inset": EffectParameter(
                0.0, "1", 0.0, 1.0, "assumed", "its centre's distance back up the leg, in radii", neutral=0.0
            ),
        },
    )
]
