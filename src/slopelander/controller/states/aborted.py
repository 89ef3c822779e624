"""ABORTED: a landing that cannot continue safely is handed back to the pilot and autopilot."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Aborted(State):
    """The reflex is disarmed, the script released, the autopilot holds position in LOITER."""

    name = "ABORTED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_abort()
        ctx.act.release()
        if inp.armed and inp.mode == "GUIDED":
            ctx.act.set_mode("LOITER")
        return None
