"""LANDED, TAKEOFF, RESET, READY: on the ground disarmed; on command take off, loosen, re-preset."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Landed(State):
    name = "LANDED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_abort()
        return None

    def step(self, ctx: Context, inp: Inputs):
        if inp.armed and inp.t - ctx.entered_at > 1.0 and not inp.takeoff_request:
            ctx.act.disarm()  # the disarm is re-sent until it takes
        if inp.takeoff_request:
            return ("TAKEOFF", "take-off commanded")
        return None


class Takeoff(State):
    name = "TAKEOFF"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.release()
        ctx.act.takeoff(ctx.cfg["takeoff.clear_height_m"] * 2)
        return None

    def step(self, ctx: Context, inp: Inputs):
        if inp.range_m is not None and inp.range_m >= ctx.cfg["takeoff.clear_height_m"]:
            return ("RESET", f"clear of the ground at {inp.range_m:.2f} m")
        return None


class Reset(State):
    name = "RESET"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.loosen_legs()
        return None

    def step(self, ctx: Context, inp: Inputs):
        # the springs reset the legs only once the board has let the friction go; the inputs of
        # the step that entered RESET still describe the preset before it, so wait for fresh ones
        if inp.t <= ctx.entered_at:
            return None
        if inp.legs_fault is not None:
            return ("READY", f"legs did not loosen: {inp.legs_fault}")
        if inp.legs_ready:
            return ("READY", "legs loosened: the springs reset them")
        return None


class Ready(State):
    """Flying again with the next preset on the legs; a new landing starts a new machine run."""

    name = "READY"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        if ctx.next_preset is not None:
            ctx.preset = ctx.next_preset
            ctx.act.set_legs(*ctx.preset)
        return None
