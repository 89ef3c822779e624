"""CUT: the motors are stopped and the vehicle falls; the script owns the motors until impact."""

from __future__ import annotations

from slopelander.controller.script_contract import ScriptState
from slopelander.controller.states.base import Context, Inputs, State

CUT_NO_IMPACT_S = 1.5  # the script decides within 1 s; this is the companion's backstop


class Cut(State):
    """Watches for the impact (script or the companion's own IMU rule); a cut without one aborts."""

    name = "CUT"
    reflex_owns = True

    def step(self, ctx: Context, inp: Inputs):
        if inp.script_state in (ScriptState.RVT, ScriptState.HOLD) or inp.impact:
            ctx.marks["impact"] = inp.t
            return ("REVERSE", "impact")
        if inp.script_state == ScriptState.IDLE:
            return ("ABORTED", "script returned to IDLE after the cut: false cut, autopilot flies")
        if inp.t - ctx.entered_at > CUT_NO_IMPACT_S:
            return ("ABORTED", "no impact after the cut")
        return None
