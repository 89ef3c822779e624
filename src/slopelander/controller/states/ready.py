"""READY: flying again with the next preset on the legs, so the next landing can follow."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Ready(State):
    """Applies the next preset; a new landing starts a new machine run."""

    name = "READY"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        if ctx.next_preset is not None:
            ctx.preset = ctx.next_preset
            ctx.act.set_legs(*ctx.preset)
        return None
