"""The base physics' own shape, freed: alternatives a named effect must beat before it is believed.

Real drops always differ a little from the model's base physics: its feet's stick/slip, its joints'
single slip torque. A candidate effect refitted on such drops can absorb that difference and pass
the test over drops as if it were a mechanism (a joint whose friction weakens with speed read as a
viscous joint, p 0.016-0.031: benchmarks/results/2026-12-07-departures.md). These effects free the
base laws' shape instead of adding a mechanism; :func:`slopelander.ident.diagnose.diagnose` refits
them when a candidate passes, and a candidate that does not beat each of them on held-out drops is
not named (:meth:`slopelander.ident.diagnose.Diagnosis.kind` ``base_physics``).

- ``joint_breakaway``: the joints' friction weakens with speed (breakaway above the slip torque),
  tau (1 + joint_breakaway exp(-(w / joint_breakaway_rate)^2)) at the leg's rate w.
- ``friction_width``: the feet's sliding friction regularised over a slip-speed width, mu
  tanh(|v| / friction_width) (0: the model's law).
"""

from __future__ import annotations

import math

import numba

from slopelander.model.effects import EffectParameter, UserEffect


@numba.njit
def _breakaway(t, st, ctx, up, leg, angle, rate, tau):
    return tau * (1.0 + up[0] * math.exp(-((rate / up[1]) ** 2)))


@numba.njit
def _width(t, st, ctx, up, leg, slip_speed, normal_force, mu):
    if up[0] <= 0.0:
        return mu
    return mu * math.tanh(abs(slip_speed) / up[0])


BASE_ALTERNATIVES: list[UserEffect] = [
    UserEffect(
        "joint_breakaway",
        "another joint law: friction weakening with speed",
        joint_torque=_breakaway,
        parameters={
            "joint_breakaway": EffectParameter(
                0.0, "1", 0.0, 1.0, "assumed", "breakaway torque over slip torque, minus one", neutral=0.0
            ),
            "joint_breakaway_rate": EffectParameter(
                5.0, "rad/s", 0.5, 20.0, "assumed", "leg rate at which the excess falls to 1/e"
            ),
        },
    ),
    UserEffect(
        "friction_width",
        "another friction regularisation: tanh over a slip-speed width",
        foot_friction=_width,
        parameters={
            "friction_width": EffectParameter(
                0.0, "m/s", 0.0, 0.02, "assumed", "slip speed of the tanh regularisation", neutral=0.0
            )
        },
    ),
]
"""The shipped base-physics alternatives, by default those :func:`diagnose` weighs a named
candidate against."""
