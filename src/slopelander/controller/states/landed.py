"""LANDED: on the slope and disarmed (the HEARTBEAT said so); waits for the pilot's take-off."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.states.settled import request_disarm


class Landed(State):
    """Entered only with the vehicle seen disarmed. Should the HEARTBEAT show it armed again
    before any take-off request (a late or reordered heartbeat, a pilot's arm), the disarm is
    asked for again until a take-off is requested: LANDED never stays armed by the companion's
    doing. The on-board script went idle by itself when the vehicle disarmed."""

    name = "LANDED"

    def step(self, ctx: Context, inp: Inputs):
        if inp.takeoff_request:
            return ("TAKEOFF", "take-off commanded")
        if inp.armed:
            request_disarm(ctx, inp)
        return None
