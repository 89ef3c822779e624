"""LANDED: on the slope, disarmed deliberately; waits for the pilot's take-off command."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Landed(State):
    """Disarms the reflex, re-sends the disarm until it takes, and leaves on a take-off request.

    Once the vehicle has been seen disarmed, a later arm is the pilot's: it is not undone."""

    name = "LANDED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_abort()
        ctx.marks.pop("landed_disarmed", None)
        if not inp.armed:
            ctx.marks["landed_disarmed"] = inp.t
        return None

    def step(self, ctx: Context, inp: Inputs):
        if not inp.armed:
            ctx.marks.setdefault("landed_disarmed", inp.t)
        elif "landed_disarmed" not in ctx.marks and inp.t - ctx.entered_at > 1.0 and not inp.takeoff_request:
            ctx.act.disarm()  # the disarm is re-sent until it takes
        if inp.takeoff_request:
            return ("TAKEOFF", "take-off commanded")
        return None
