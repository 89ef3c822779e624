"""ARMED: near the ground the on-board reflex, not the companion, must cut the motors in time."""

from __future__ import annotations

from slopelander.controller.script_contract import ScriptState, state_name
from slopelander.controller.script_rules import REFLEX_HELD
from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.stuck_range import range_stuck


class Armed(State):
    """Re-sends the reflex arm before its validity lapses; the script's state tells when it has
    cut the motors or felt the impact. The descent below the arm height goes on only once the
    script reports its reflex armed: until then the vehicle hovers, and without that report
    within ``reflex.confirm_timeout_s`` (a refusal: emergency stop, a system-id mismatch, no
    rangefinder) the landing is aborted in the air, motors running, rather than flown into the
    roof with nobody to cut them. A range that stops changing while the vehicle descends (the
    script would never cut on it) aborts too (controller/stuck_range.py)."""

    name = "ARMED"
    airborne_descent = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_arm()
        ctx.marks["reflex_sent"] = inp.t
        return None

    def step(self, ctx: Context, inp: Inputs):
        if not inp.armed:
            # the autopilot disarmed (its land detector: the feet met the roof before the range
            # reached the cut height): the script cannot cut any more, so waiting here is for ever
            if inp.range_valid and inp.range_m <= ctx.cfg["reflex.arm_height_m"]:
                return ("LANDED", "disarmed by the autopilot before the cut: on the ground")
            return ("ABORTED", "disarmed by the autopilot in the air")
        if inp.script_state == ScriptState.CUT:
            return ("CUT", "on-board script cut the motors")
        if inp.script_state in (ScriptState.RVT, ScriptState.HOLD):  # cut and impact between two steps
            return ("CUT", "on-board script cut the motors and reports impact")
        stuck = range_stuck(ctx, inp)
        if stuck is not None:
            return ("ABORTED", stuck)
        confirmed = inp.script_state in REFLEX_HELD
        if confirmed:
            ctx.marks["reflex_confirmed"] = True
        elif not ctx.marks.get("reflex_confirmed"):
            waited = inp.t - ctx.entered_at
            if waited > ctx.cfg["reflex.confirm_timeout_s"]:
                state = state_name(inp.script_state)
                return ("ABORTED", f"on-board reflex not armed after {waited:.2f} s (script {state})")
        # a script that let go of an armed reflex (its validity lapsed, a reboot) stops the descent too
        ctx.act.descend(ctx.cfg["descent.rate_mps"] if confirmed else 0.0)
        if inp.t - ctx.marks["reflex_sent"] >= ctx.cfg["reflex.refresh_s"]:
            ctx.act.reflex_arm()
            ctx.marks["reflex_sent"] = inp.t
        if not confirmed and ctx.marks.get("reflex_confirmed"):
            now = state_name(inp.script_state)
            return ("ABORTED", f"on-board reflex let go before the cut (script {now})")
        return None
