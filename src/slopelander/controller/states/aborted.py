"""ABORTED: a landing that cannot continue safely is handed back to the pilot and autopilot."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State

#: vehicle seconds between asks for LOITER while the autopilot still reports GUIDED, armed
REASK_S = 1.0
#: asks after which the pilot is told the autopilot has not taken LOITER (they go on)
TELL_AFTER = 5


class Aborted(State):
    """The reflex is disarmed, the script released, the autopilot holds position in LOITER.

    LOITER is asked for again every ``REASK_S`` while the autopilot still reports GUIDED and
    armed: one mode command and its retries can all be lost (the link just back from a cut, seen
    in a loaded suite, 2026-11-27), and in GUIDED with no setpoints coming the vehicle only holds
    until the pilot notices. A mode other than GUIDED is the pilot's (or the autopilot's own
    failsafe) and is left alone."""

    name = "ABORTED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_abort()
        ctx.act.release()
        if inp.armed and inp.mode == "GUIDED":
            ctx.act.set_mode("LOITER")
            ctx.marks["loiter_asks"] = (1, inp.t)
        return None

    def step(self, ctx: Context, inp: Inputs):
        asks, last = ctx.marks.get("loiter_asks", (0, inp.t))
        if asks and inp.armed and inp.mode == "GUIDED" and inp.t - last >= REASK_S:
            ctx.act.set_mode("LOITER")
            ctx.marks["loiter_asks"] = (asks + 1, inp.t)
            if asks + 1 == TELL_AFTER:
                ctx.act.statustext(f"SL LOITER not taken after {TELL_AFTER} asks: take over")
        return None
