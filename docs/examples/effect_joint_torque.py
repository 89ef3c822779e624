"""A viscous friction joint: its slip torque grows with the joint's speed.

Seam: the friction joint's torque law. The integrator calls ``joint_torque`` every step for
each leg with the joint's angle, the leg's angular rate (rad/s, negative while compressing;
the joint's slip rate while the leg does not bend) and the torque the built-in model would
use (the set torque, grown by eq. 3 on the downhill leg if that effect is on); the value
returned is the slip torque of that step (planar leg: both real joints).

    tau = tau_builtin * (1 + joint_viscous_gain * |rate|)

Use it with ``slopelander diagnose --candidates docs/examples/effect_joint_torque.py`` or
``Model.with_user_effect(load_effects(path)[0])``.
"""

import numba

from slopelander.model.effects import EffectParameter, UserEffect


@numba.njit
def viscous_joint(t, st, ctx, up, leg, angle, rate, tau):
    gain = up[0]
    return tau * (1.0 + gain * abs(rate))


EFFECTS = [
    UserEffect(
        "viscous_joint",
        "friction-joint torque grows with the joint's speed (eddy-current or oil damping)",
        joint_torque=viscous_joint,
        parameters={
            "joint_viscous_gain": EffectParameter(
                0.05, "s/rad", 0.0, 0.2, "assumed", "fractional torque rise per rad/s", neutral=0.0
            )
        },
    )
]
