"""PRESET: command the landing torques on the legs (and the uphill angle where the board can set it)."""

from __future__ import annotations

from slopelander.controller.states.aborted import abort_rising
from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.states.settled import reads_near_the_roof


class Preset(State):
    """Starts the leg operation; the board takes seconds, so waiting is the next state's job."""

    name = "PRESET"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        why = ctx.act.check_preset(*ctx.preset)  # refused on the ground, not found out in flight
        if why is not None:
            return why
        angle = ctx.uphill_angle_deg
        if angle is None:
            ctx.act.set_legs(*ctx.preset)
        elif ctx.act.can_set_angle():
            ctx.act.set_legs(*ctx.preset, angle)
        else:  # legs without an angle actuator (the paper's): the pilot sets it; CHECKS verifies
            ctx.act.statustext(f"SL set uphill legs to {angle:.1f} deg by hand")
            ctx.act.set_legs(*ctx.preset)
        return None

    def step(self, ctx: Context, inp: Inputs):
        low = reads_near_the_roof(ctx.cfg, inp)
        if low is not None:
            return abort_rising(ctx, low)
        return ("LEGS_WAIT", f"legs commanded to {ctx.preset[0]:.2f}/{ctx.preset[1]:.2f} N*m")
