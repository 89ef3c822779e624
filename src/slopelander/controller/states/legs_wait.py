"""LEGS_WAIT: the descent must not start before every leg holds its landing torque."""

from __future__ import annotations

from slopelander.controller.states.aborted import abort_rising
from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.states.settled import reads_near_the_roof


def reported_angles(inp: Inputs) -> str:
    """ " at UP/DOWN deg": the pairs' mean angles as the board reports them, for the transition's
    reason, which the autopilot's log keeps (the companion's STATUSTEXT, 50 characters: ArduPilot
    logs it as MSG), so ``slopelander compare FLIGHT.bin`` reads the legs as flown; "" when unknown."""
    if not inp.uphill_angles_deg or not inp.downhill_angles_deg:
        return ""
    up = sum(inp.uphill_angles_deg) / len(inp.uphill_angles_deg)
    down = sum(inp.downhill_angles_deg) / len(inp.downhill_angles_deg)
    return f" at {up:.1f}/{down:.1f} deg"


class LegsWait(State):
    """Waits for the board to report the preset within tolerance, bounded by ``legs.ready_timeout_s``."""

    name = "LEGS_WAIT"

    def step(self, ctx: Context, inp: Inputs):
        low = reads_near_the_roof(ctx.cfg, inp)
        if low is not None:
            return abort_rising(ctx, low)
        if inp.legs_ready:
            return ("CHECKS", "legs within tolerance" + reported_angles(inp))
        if inp.t - ctx.entered_at > ctx.cfg["legs.ready_timeout_s"]:
            return ("ABORTED", "legs not within tolerance in time")
        return None
