"""Lead-screw backlash in the friction joints: an effect with memory.

The FSA's friction joint drives its leg through a lead screw with some play: when the torque
on the joint reverses, the joint crosses the gap freely before the screw's friction takes hold
again. Which flank of the gap the screw rests on is history, not state the model has, so the
effect declares it as memory: ``lash_C`` and ``lash_D``, each the screw's place in its gap as a
fraction (0: taken up on the compression flank, 1: on the extension flank). Legs are set by
extending them, so both start at 1 and an impact's compression first crosses the gap.

Seams: the friction joint's torque law (``joint_torque``) reads the memory: the joint holds with
its full torque while the leg pushes it against the flank the screw rests on, and slips freely
(zero torque) otherwise; it notes which (``held_C``, ``held_D``). ``update`` runs once per step
after it and moves a free screw through its gap by the joint's motion over the step, held within
the gap's flanks; a held screw moves with its joint, so its place in the gap stays. Which way the
leg pushes its joint is ``state.joint_load(ctx)`` (the leg's torque on it, + toward extension).

    gap = backlash_deg;  held: lash stays;  free: lash += (joint's motion this step) / gap, in 0..1
    tau = tau_builtin  if the leg pushes toward the flank the screw rests on, else 0

At ``backlash_deg = 0`` it returns the built-in torque and never touches its memory: a landing
is the base model's to the last bit (tests/model/test_effect_examples.py).
"""

import math

import numba

from slopelander.model import state
from slopelander.model.effects import EffectParameter, EffectState, UserEffect


@numba.njit
def backlash_torque(t, st, ctx, up, leg, angle, rate, tau):
    gap = up[0]
    if gap <= 0.0:
        return tau
    lash = state.memory(st, ctx, leg)
    load = state.joint_load(ctx)  # the leg's torque on the joint: > 0 toward extension
    # pushed onto the flank the screw rests on (or resting there unloaded): the screw holds
    held = (lash <= 0.0 and load <= 0.0) or (lash >= 1.0 and load >= 0.0)
    state.set_memory(st, ctx, 2 + leg, 1.0 if held else 0.0)
    return tau if held else 0.0  # crossing the gap: nothing holds the joint


@numba.njit
def backlash_update(t, st, ctx, up, h):
    gap = up[0] * math.pi / 180.0
    if gap <= 0.0:
        return
    for leg in range(2):
        if state.memory(st, ctx, 2 + leg) == 0.0:  # free this step: the joint moved in the gap
            lash = state.memory(st, ctx, leg) + state.joint_rate(st, leg) * h / gap
            state.set_memory(st, ctx, leg, min(1.0, max(0.0, lash)))


EFFECTS = [
    UserEffect(
        "lead_screw_backlash",
        "the friction joints' lead screws have play: after the joint's torque reverses, the joint "
        "crosses the gap freely before the screw holds again",
        joint_torque=backlash_torque,
        update=backlash_update,
        parameters={
            "backlash_deg": EffectParameter(
                3.0, "deg", 0.0, 10.0, "assumed", "free play of the joint's lead screw", neutral=0.0
            )
        },
        states={
            "lash_C": EffectState(1.0, "1", "leg C's screw in its gap: 0 compression flank, 1 extension"),
            "lash_D": EffectState(1.0, "1", "leg D's screw in its gap: 0 compression flank, 1 extension"),
            "held_C": EffectState(0.0, "1", "1 while leg C's screw holds on a flank this step"),
            "held_D": EffectState(0.0, "1", "1 while leg D's screw holds on a flank this step"),
        },
    )
]
