"""ABORTED: a landing that cannot continue safely is handed back to the pilot and autopilot."""

from __future__ import annotations

from slopelander.controller.script_contract import ScriptState
from slopelander.controller.script_rules import STOPS_DESCENT
from slopelander.controller.states.base import SCRIPT_LANDING, Context, Inputs, State

#: vehicle seconds between asks for LOITER while the autopilot still reports GUIDED, armed
REASK_S = 1.0
#: asks after which the pilot is told the autopilot has not taken LOITER (they go on)
TELL_AFTER = 5
#: the climb (m/s, up) asked first, before the mode change: the descent's target stops at once
CLIMB_MPS = 0.3
#: the vehicle reads no faster down than this (m/s) ...
NOT_DESCENDING_MPS = 0.05
#: ... for this long (vehicle s) before the reflex is let go: the vehicle is climbing or holding
HOLDING_S = 0.3
#: the script's states the abort keeps as they are until the vehicle climbs or holds
KEEP_UNTIL_HOLDING = frozenset({ScriptState.ARMED}) | STOPS_DESCENT


class Aborted(State):
    """The descent is stopped first, then the autopilot is asked to hold position in LOITER; the
    on-board reflex stays armed until the vehicle is known to be climbing or holding (the autopilot
    reports LOITER, or the vehicle reads not descending for ``HOLDING_S``), and is then disarmed
    and the script released.

    The order matters: the GUIDED descent target runs on until ``GUID_TIMEOUT`` (1 s in the
    parameter files since contract 5, 3 s before) after the companion's last setpoint, so a lost
    LOITER command after the reflex was let go flew the vehicle into the roof under power with
    nobody to cut it. Now a climb setpoint goes first (and is re-sent while in GUIDED), the mode
    second, and if the roof comes anyway the reflex still cuts the motors: the landing goes on in
    CUT.

    LOITER is asked for again every ``REASK_S`` while the autopilot still reports GUIDED and
    armed: one mode command and its retries can all be lost (the link just back from a cut, seen
    in a loaded suite, 2026-11-27). A mode other than GUIDED is the pilot's (or the autopilot's own
    failsafe) and is left alone: the reflex is let go at once."""

    name = "ABORTED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        if inp.armed and inp.mode == "GUIDED":
            ctx.act.hold(CLIMB_MPS)
            ctx.act.set_mode("LOITER")
            ctx.marks["loiter_asks"] = (1, inp.t)
            # a reflex to keep, or the script's own climb (its reflex lapsed, or it failed in the
            # descent: ABORT would end that climb), until the vehicle climbs or holds
            if inp.script_present and inp.script_state in KEEP_UNTIL_HOLDING:
                ctx.marks["abort_pending"] = True
                ctx.marks["abort_holding_since"] = None
                return None
        self._let_go(ctx)
        return None

    @staticmethod
    def _let_go(ctx: Context) -> None:
        ctx.act.reflex_abort()
        ctx.act.release()
        ctx.marks["abort_pending"] = False

    def step(self, ctx: Context, inp: Inputs):
        m = ctx.marks
        if m.get("abort_pending"):
            move = self._hold_until_safe(ctx, inp)
            if move is not None:
                return move
        asks, last = m.get("loiter_asks", (0, inp.t))
        if asks and inp.armed and inp.mode == "GUIDED" and inp.t - last >= REASK_S:
            ctx.act.set_mode("LOITER")
            m["loiter_asks"] = (asks + 1, inp.t)
            if asks + 1 == TELL_AFTER:
                ctx.act.statustext(f"SL LOITER not taken after {TELL_AFTER} asks: take over")
        return None

    def _hold_until_safe(self, ctx: Context, inp: Inputs):
        m = ctx.marks
        if inp.script_state in SCRIPT_LANDING:  # the roof came first: the reflex cut, land on
            m["abort_pending"] = False
            return ("CUT", "on-board script cut the motors during the abort: landing on")
        if not inp.armed or inp.mode != "GUIDED":  # disarmed, or LOITER (the autopilot holds)
            self._let_go(ctx)
            return None
        # re-sent at the descent's rate while GUIDED; the reflex is not refreshed (the reason for the
        # abort may be the range it cuts on): it stays armed for what is left of its validity
        # (``reflex.validity_ms``), more than the climb takes to show
        ctx.act.descend(-CLIMB_MPS)
        rising = inp.climb_mps is not None and inp.climb_mps >= -NOT_DESCENDING_MPS
        if not rising:
            m["abort_holding_since"] = None
        elif m.get("abort_holding_since") is None:
            m["abort_holding_since"] = inp.t
        elif inp.t - m["abort_holding_since"] >= HOLDING_S:
            self._let_go(ctx)
        return None
