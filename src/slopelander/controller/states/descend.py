"""DESCEND and ARMED: descend at the set rate; near the ground, keep the on-board reflex armed."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Descend(State):
    name = "DESCEND"
    airborne_descent = True

    def step(self, ctx: Context, inp: Inputs):
        ctx.act.descend(ctx.cfg["descent.rate_mps"])
        if inp.range_m is not None and inp.range_m <= ctx.cfg["reflex.arm_height_m"]:
            return ("ARMED", f"range {inp.range_m:.2f} m: arming the reflex")
        return None


class Armed(State):
    name = "ARMED"
    airborne_descent = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_arm()
        ctx.marks["reflex_sent"] = inp.t
        return None

    def step(self, ctx: Context, inp: Inputs):
        ctx.act.descend(ctx.cfg["descent.rate_mps"])
        if inp.t - ctx.marks["reflex_sent"] >= ctx.cfg["reflex.refresh_s"]:
            ctx.act.reflex_arm()
            ctx.marks["reflex_sent"] = inp.t
        if inp.script_state == 11:
            return ("CUT", "on-board script cut the motors")
        if inp.script_state in (12, 13):
            return ("REVERSE", "on-board script reports impact")
        return None
