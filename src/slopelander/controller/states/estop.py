"""ESTOP: after an emergency stop nothing the companion sends may restart the motors."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Estop(State):
    """The script releases everything by itself; the companion disarms its reflex, then commands nothing."""

    name = "ESTOP"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.reflex_abort()
        return None
