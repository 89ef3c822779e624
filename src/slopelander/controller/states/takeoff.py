"""TAKEOFF: the legs stay clamped until the vehicle is clear, or a leg could drop onto the slope."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Takeoff(State):
    """Releases the script, takes off, and moves on once the range shows the vehicle clear."""

    name = "TAKEOFF"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.release()
        ctx.act.takeoff(ctx.cfg["takeoff.clear_height_m"] * 2)
        return None

    def step(self, ctx: Context, inp: Inputs):
        # a stale or invalid reading must never loosen the legs on the ground
        if inp.range_valid and inp.range_m >= ctx.cfg["takeoff.clear_height_m"]:
            return ("RESET", f"clear of the ground at {inp.range_m:.2f} m")
        return None
