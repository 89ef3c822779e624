"""The paper's eq. 3 written as a user effect: a joint's torque grows with its foot's friction
force while that force points inward (the foot is pushed outward, bending the leg back),
tau * (1 + factor * max(0, F_inward)). On a slope that is the paper's downhill leg; on level
ground both splaying legs, so there is no switch at 0 deg.

Seam: the friction joint's torque law. This is the built-in ``downhill_torque_growth`` effect
(parameter ``factor_tau``) expressed through the user-effect API; with the built-in switched
off and the same factor, a landing is identical to the built-in's
(tests/model/test_effect_examples.py). Eq. 4 (``downhill_friction_growth``) cannot be written
this way as it stands: it reads its leg's joint velocity, which the foot-friction seam
does not receive (a user law could compute it from the state with the kinematics).
"""

import numba

from slopelander.model import state
from slopelander.model.effects import EffectParameter, UserEffect


@numba.njit
def torque_growth(t, st, ctx, up, leg, angle, rate, tau):
    # friction along the surface tangent (+x side): inward is + for leg C (0), - for leg D (1)
    inward = state.friction_force(st, leg) * (1.0 if leg == 0 else -1.0)
    return tau * (1.0 + up[0] * max(0.0, inward))


EFFECTS = [
    UserEffect(
        "torque_growth_eq3",
        "a joint's torque grows with its foot's inward friction force (eq. 3, as a user effect)",
        joint_torque=torque_growth,
        parameters={
            "eq3_factor": EffectParameter(5.8e-4, "1/N", 0.0, 0.01, "paper", "Table II", neutral=0.0)
        },
    )
]
