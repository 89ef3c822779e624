"""LEGS_WAIT: the descent must not start before every leg holds its landing torque."""

from __future__ import annotations

from slopelander.controller.states.aborted import abort_rising
from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.states.settled import reads_near_the_roof


class LegsWait(State):
    """Waits for the board to report the preset within tolerance, bounded by ``legs.ready_timeout_s``."""

    name = "LEGS_WAIT"

    def step(self, ctx: Context, inp: Inputs):
        low = reads_near_the_roof(ctx.cfg, inp)
        if low is not None:
            return abort_rising(ctx, low)
        if inp.legs_ready:
            return ("CHECKS", "legs within tolerance")
        if inp.t - ctx.entered_at > ctx.cfg["legs.ready_timeout_s"]:
            return ("ABORTED", "legs not within tolerance in time")
        return None
