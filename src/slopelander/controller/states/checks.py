"""CHECKS: everything the landing relies on, verified once before the descent starts."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


def refusal(inp: Inputs) -> str | None:
    """The first failed pre-descent check, or None."""
    if not inp.script_present:
        return "on-board script not present"
    if not inp.range_ok:
        return "rangefinder not healthy"
    if not inp.legs_ready:
        return "legs not ready"
    if inp.mode != "GUIDED":
        return f"mode {inp.mode}, GUIDED needed"
    if not inp.armed:
        return "vehicle not armed"
    return None


class Checks(State):
    name = "CHECKS"

    def step(self, ctx: Context, inp: Inputs):
        why = refusal(inp)
        if why is not None:
            return ("ABORTED", f"check failed: {why}")
        return ("DESCEND", "checks passed")
