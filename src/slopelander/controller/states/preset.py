"""PRESET and LEGS_WAIT: set the landing torques and wait until every leg reports them."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Preset(State):
    name = "PRESET"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.set_legs(*ctx.preset)
        return None

    def step(self, ctx: Context, inp: Inputs):
        return ("LEGS_WAIT", f"legs commanded to {ctx.preset[0]:.2f}/{ctx.preset[1]:.2f} N*m")


class LegsWait(State):
    name = "LEGS_WAIT"

    def step(self, ctx: Context, inp: Inputs):
        if inp.legs_ready:
            return ("CHECKS", "legs within tolerance")
        if inp.t - ctx.entered_at > ctx.cfg["legs.ready_timeout_s"]:
            return ("ABORTED", "legs not within tolerance in time")
        return None
