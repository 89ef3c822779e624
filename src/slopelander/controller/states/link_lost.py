"""LINK_LOST: nothing can be sent, so safety rests on the autopilot's and the script's own timeouts."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class LinkLost(State):
    """On board: GUID_TIMEOUT stops the descent, the reflex validity lapses, a HOLD disarms when its
    validity lapses. When the link returns, abort to LOITER."""

    name = "LINK_LOST"

    def step(self, ctx: Context, inp: Inputs):
        if inp.link_ok:
            return ("ABORTED", "link back: aborting the landing")
        return None
