"""ARMED: near the ground the on-board reflex, not the companion, must cut the motors in time."""

from __future__ import annotations

from slopelander.controller.script_contract import ScriptState
from slopelander.controller.states.base import Context, Inputs, State


class Armed(State):
    """Keeps descending and re-sends the reflex arm before its validity lapses; the script's
    state tells when it has cut the motors or felt the impact."""

    name = "ARMED"
    airborne_descent = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_arm()
        ctx.marks["reflex_sent"] = inp.t
        return None

    def step(self, ctx: Context, inp: Inputs):
        if not inp.armed:
            # the autopilot disarmed (its land detector: the feet met the roof before the range
            # reached the cut height): the script cannot cut any more, so waiting here is for ever
            if inp.range_valid and inp.range_m <= ctx.cfg["reflex.arm_height_m"]:
                return ("LANDED", "disarmed by the autopilot before the cut: on the ground")
            return ("ABORTED", "disarmed by the autopilot in the air")
        ctx.act.descend(ctx.cfg["descent.rate_mps"])
        if inp.t - ctx.marks["reflex_sent"] >= ctx.cfg["reflex.refresh_s"]:
            ctx.act.reflex_arm()
            ctx.marks["reflex_sent"] = inp.t
        if inp.script_state == ScriptState.CUT:
            return ("CUT", "on-board script cut the motors")
        # cut and impact both fell between two steps
        if inp.script_state in (ScriptState.RVT, ScriptState.HOLD):
            return ("CUT", "on-board script cut the motors and reports impact")
        return None
