"""ABORTED, ESTOP and LINK_LOST: the endings that leave the vehicle to the pilot and autopilot."""

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


class Estop(State):
    """Emergency stop: the script releases everything by itself; the companion commands nothing."""

    name = "ESTOP"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_abort()
        return None


class LinkLost(State):
    """Nothing can be sent. On board: GUID_TIMEOUT stops the descent, the reflex validity lapses,
    a HOLD disarms when its validity lapses. When the link returns, abort to LOITER."""

    name = "LINK_LOST"

    def step(self, ctx: Context, inp: Inputs):
        if inp.link_ok:
            return ("ABORTED", "link back: aborting the landing")
        return None
