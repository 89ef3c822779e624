"""The paper's eq. 3 written as a user effect: the downhill joint's torque grows with its
foot's friction force, tau * (1 + factor * |F_foot|).

Seam: the friction joint's torque law. This is the built-in ``downhill_torque_growth`` effect
(parameter ``factor_tau``) expressed through the user-effect API; with the built-in switched
off and the same factor, a landing is identical to the built-in's
(tests/model/test_effect_examples.py). Eq. 4 (``downhill_friction_growth``) cannot be written
this way as it stands: it reads the downhill joint's velocity, which the foot-friction seam
does not receive (a user law could compute it from the state with the kinematics).
"""

import numba

from slopelander.model import state
from slopelander.model.effects import EffectParameter, UserEffect


@numba.njit
def torque_growth(t, st, ctx, up, leg, angle, rate, tau):
    if state.slope_sin(ctx) == 0.0 or leg != state.downhill_leg(ctx):
        return tau  # only the downhill leg, and level ground has none
    return tau * (1.0 + up[0] * abs(state.friction_force(st, leg)))


EFFECTS = [
    UserEffect(
        "torque_growth_eq3",
        "downhill joint torque grows with its foot's friction force (eq. 3, as a user effect)",
        joint_torque=torque_growth,
        parameters={
            "eq3_factor": EffectParameter(5.8e-4, "1/N", 0.0, 0.01, "paper", "Table II", neutral=0.0)
        },
    )
]
