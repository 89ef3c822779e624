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
#: the states an abort may come from close over the roof: the vehicle climbs first, LOITER after
NEAR_THE_ROOF = frozenset({"DESCEND", "ARMED", "CUT"})
#: how far (m, by LOCAL_POSITION_NED) such an abort climbs before LOITER is asked, at RISE_MPS ...
RISE_M = 1.0
RISE_MPS = 0.5
#: ... or for at most this long (vehicle s), whichever comes first
RISE_MAX_S = 4.0
#: the rise ends with a hold setpoint, and LOITER is asked once the climb has slowed under this
#: (m/s) or after STOP_MAX_S: LOITER takes a vehicle at rest, not one still climbing (taken at
#: 0.5 m/s the simulated vehicle overshot and sank back at 0.11 m/s)
STOPPED_MPS = 0.1
STOP_MAX_S = 1.0


def abort_rising(ctx: Context, why: str) -> tuple[str, str]:
    """The transition to ABORTED from a state before the descent, climbing :data:`RISE_M` first as
    from the descent: the vehicle was found near the roof there."""
    ctx.marks["abort_rise"] = True
    return ("ABORTED", why)


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
    failsafe) and is left alone: the reflex is let go at once.

    An abort from the descent (:data:`NEAR_THE_ROOF`) climbs :data:`RISE_M` in GUIDED before
    LOITER is asked (at most :data:`RISE_MAX_S`): LOITER holds the height it is given, and a 200-
    landing soak on ArduCopter left a vehicle whose range stuck at 0.34 m hovering armed 0.17 m
    over the roof. From the states before the descent the vehicle hovers at its approach height
    and LOITER is asked at once, unless it was found near the roof there (:func:`abort_rising`)."""

    name = "ABORTED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        if inp.armed and inp.mode == "GUIDED":
            ctx.act.hold(CLIMB_MPS)
            near = ctx.previous in NEAR_THE_ROOF or ctx.marks.pop("abort_rise", False)
            if near and inp.position_m is not None:
                ctx.marks["abort_rise_from"] = (-inp.position_m[2], inp.t)
                ctx.marks["loiter_asks"] = (0, inp.t)
            else:
                self.ask_loiter(ctx, inp)
            # a reflex to keep, or the script's own climb (its reflex lapsed, or it failed in the
            # descent: ABORT would end that climb), until the vehicle climbs or holds
            if inp.script_present and inp.script_state in KEEP_UNTIL_HOLDING:
                ctx.marks["abort_pending"] = True
                ctx.marks["abort_holding_since"] = None
                return None
        self._let_go(ctx)
        return None

    @staticmethod
    def ask_loiter(ctx: Context, inp: Inputs) -> None:
        """LOITER asked (again every ``REASK_S`` while GUIDED); the rise, if any, is over."""
        ctx.marks.pop("abort_rise_from", None)
        ctx.marks.pop("abort_rise_stop", None)
        ctx.act.set_mode("LOITER")
        ctx.marks["loiter_asks"] = (1, inp.t)

    @staticmethod
    def rising(ctx: Context) -> bool:
        """Whether the climb before LOITER is still under way (the runner keeps stepping)."""
        return "abort_rise_from" in ctx.marks

    def _rise(self, ctx: Context, inp: Inputs) -> None:
        """The climb before LOITER: re-sent at the descent's rate while GUIDED and armed; once
        risen :data:`RISE_M` a hold setpoint, and LOITER when the climb has stopped (or after
        :data:`STOP_MAX_S`); LOITER at once after :data:`RISE_MAX_S` or when the position is lost."""
        if not inp.armed or inp.mode != "GUIDED":  # the pilot's or the autopilot's: left alone
            ctx.marks.pop("abort_rise_from", None)
            return
        alt0, t0 = ctx.marks["abort_rise_from"]
        pos = inp.position_m
        stop_at = ctx.marks.get("abort_rise_stop")
        if stop_at is not None:  # risen: the hold setpoint is sent, LOITER once at rest
            slowed = inp.climb_mps is None or abs(inp.climb_mps) <= STOPPED_MPS
            if slowed or inp.t - stop_at >= STOP_MAX_S:
                self.ask_loiter(ctx, inp)
            return
        if pos is None or inp.t - t0 >= RISE_MAX_S:
            self.ask_loiter(ctx, inp)
            return
        if -pos[2] - alt0 >= RISE_M:
            ctx.act.hold(0.0)
            ctx.marks["abort_rise_stop"] = inp.t
            return
        ctx.act.descend(-RISE_MPS)

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
        if "abort_rise_from" in m:
            self._rise(ctx, inp)
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
        if "abort_rise_from" not in m:  # the rise before LOITER sends its own, faster
            ctx.act.descend(-CLIMB_MPS)
        rising = inp.climb_mps is not None and inp.climb_mps >= -NOT_DESCENDING_MPS
        if not rising:
            m["abort_holding_since"] = None
        elif m.get("abort_holding_since") is None:
            m["abort_holding_since"] = inp.t
        elif inp.t - m["abort_holding_since"] >= HOLDING_S:
            self._let_go(ctx)
        return None
