"""RESET: the legs' springs only return them to their rest angle once the friction is let go."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Reset(State):
    """Loosens every leg and waits for the board to report them loose."""

    name = "RESET"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.loosen_legs()
        return None

    def step(self, ctx: Context, inp: Inputs):
        # the inputs of the step that entered RESET still describe the preset before it
        if inp.t <= ctx.entered_at:
            return None
        if inp.legs_fault is not None:
            return ("READY", f"legs did not loosen: {inp.legs_fault}")
        if inp.legs_ready:
            return ("READY", "legs loosened: the springs reset them")
        if inp.t - ctx.entered_at > ctx.cfg["legs.ready_timeout_s"]:
            return ("READY", "legs did not report loose in time: check them before the next landing")
        return None
