"""DESCEND: the controlled descent at the configured rate, until the ground is near."""

from __future__ import annotations

from slopelander.controller.script_contract import ScriptState
from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.stuck_range import StuckRange, range_stuck


class Descend(State):
    """Streams the descent setpoint; near the ground (``reflex.arm_height_m``) the reflex is armed.
    A range that stops changing while the vehicle descends aborts (controller/stuck_range.py)."""

    name = "DESCEND"
    airborne_descent = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.marks["stuck_range"] = StuckRange(ctx.cfg)
        return None

    def step(self, ctx: Context, inp: Inputs):
        # armed by an earlier landing's command, or a late report
        if inp.script_state in (ScriptState.CUT, ScriptState.RVT, ScriptState.HOLD):
            ctx.act.descend(ctx.cfg["descent.rate_mps"])
            return ("CUT", "on-board script cut the motors")
        stuck = range_stuck(ctx, inp)
        if stuck is not None:
            return ("ABORTED", stuck)
        ctx.act.descend(ctx.cfg["descent.rate_mps"])
        if inp.range_valid and inp.range_m <= ctx.cfg["reflex.arm_height_m"]:
            return ("ARMED", f"range {inp.range_m:.2f} m: arming the reflex")
        return None
