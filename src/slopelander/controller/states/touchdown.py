"""CUT, REVERSE and SETTLED: the script owns the motors; the companion watches, then disarms."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State

CUT_NO_IMPACT_S = 1.5  # the script decides within 1 s; this is the companion's backstop


class Cut(State):
    name = "CUT"
    reflex_owns = True

    def step(self, ctx: Context, inp: Inputs):
        if inp.script_state in (12, 13) or inp.impact:
            ctx.marks["impact"] = inp.t
            return ("REVERSE", "impact")
        if inp.script_state == 0:
            return ("ABORTED", "script returned to IDLE after the cut: false cut, autopilot flies")
        if inp.t - ctx.entered_at > CUT_NO_IMPACT_S:
            return ("ABORTED", "no impact after the cut")
        return None


class Reverse(State):
    name = "REVERSE"
    reflex_owns = True

    def step(self, ctx: Context, inp: Inputs):
        if inp.t - ctx.entered_at >= ctx.cfg["reflex.reverse_thrust_ms"] / 1000.0 and inp.script_state != 12:
            return ("SETTLED", "reverse thrust done")
        return None


class Settled(State):
    name = "SETTLED"
    reflex_owns = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.marks["still_since"] = inp.t
        return None

    def step(self, ctx: Context, inp: Inputs):
        if abs(inp.accel_mps2 - 9.80665) > ctx.cfg["settle.still_mps2"]:
            ctx.marks["still_since"] = inp.t
        if inp.t - ctx.marks["still_since"] >= ctx.cfg["settle.still_s"]:
            ctx.act.disarm()
            return ("LANDED", "still: motors stopped, disarming")
        return None
