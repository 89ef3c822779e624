"""LANDED: on the slope and disarmed (the HEARTBEAT said so); waits for the pilot's take-off."""

from __future__ import annotations

from slopelander.controller.script_rules import DISARMS
from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.states.settled import request_disarm, request_ground_disarm


class Landed(State):
    """Entered only with the vehicle seen disarmed. Should the HEARTBEAT show it armed again
    before any take-off request (a late or reordered heartbeat, a pilot's arm), the disarm is
    asked for again until a take-off is requested: LANDED never stays armed by the companion's
    doing. The on-board script went idle by itself when the vehicle disarmed, and an idle script
    refuses a disarm; so the script is asked only while it holds the motors (HOLD, STOP, FAULT_HELD), and
    otherwise the companion sends its own unforced disarm, which ArduCopter accepts only with
    its land detector saying landed."""

    name = "LANDED"

    def step(self, ctx: Context, inp: Inputs):
        if inp.takeoff_request:
            return ("TAKEOFF", "take-off commanded")
        if inp.armed and inp.link_ok:  # a lost link's armed flag is stale, and a command lost
            if inp.script_present and inp.script_state in DISARMS:
                request_disarm(ctx, inp)
            else:
                request_ground_disarm(ctx, inp)
        return None
