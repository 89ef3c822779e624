"""DESCEND: the controlled descent at the configured rate, until the ground is near."""

from __future__ import annotations

from slopelander.controller.script_contract import ScriptState
from slopelander.controller.states.base import Context, Inputs, State


class Descend(State):
    """Streams the descent setpoint; near the ground (``reflex.arm_height_m``) the reflex is armed."""

    name = "DESCEND"
    airborne_descent = True

    def step(self, ctx: Context, inp: Inputs):
        ctx.act.descend(ctx.cfg["descent.rate_mps"])
        # armed by an earlier landing's command, or a late report
        if inp.script_state in (ScriptState.CUT, ScriptState.RVT, ScriptState.HOLD):
            return ("CUT", "on-board script cut the motors")
        if inp.range_valid and inp.range_m <= ctx.cfg["reflex.arm_height_m"]:
            return ("ARMED", f"range {inp.range_m:.2f} m: arming the reflex")
        return None
