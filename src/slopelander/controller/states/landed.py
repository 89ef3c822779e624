"""LANDED: on the slope and disarmed (the HEARTBEAT said so); waits for the pilot's take-off."""

from __future__ import annotations

from slopelander.controller.script_rules import DISARMS, FAULT_REFUSAL, faulted
from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.states.settled import request_disarm, request_ground_disarm


class Landed(State):
    """Entered only with the vehicle seen disarmed. Should the HEARTBEAT show it armed again
    before any take-off request (a late or reordered heartbeat, a pilot's arm), the disarm is
    asked for again until a take-off is requested: LANDED never stays armed by the companion's
    doing. The on-board script went idle by itself when the vehicle disarmed, and an idle script
    refuses a disarm; so the script is asked only while it holds the motors (HOLD, STOP, FAULT_HELD), and
    otherwise the companion sends its own unforced disarm, which ArduCopter accepts only with
    its land detector saying landed.

    A take-off is never asked of a script in a fault (FAULT, FAULT_HELD): it would not release the
    motors for it, nor cut or reverse on the next roof, and the soak on ArduCopter re-armed and
    flew such a vehicle, which then ended armed in LOITER at the roof. The request is refused with
    the reason (``marks["takeoff_refused"]``, one STATUSTEXT) and LANDED stays, disarmed.

    A take-off that came back here (the autopilot would not arm, the vehicle never climbed) is
    not asked again while the pilot's request still stands: the request must be let go and given
    anew (``marks["takeoff_release"]``). Without that, a held request bounced LANDED -> TAKEOFF ->
    LANDED every 10 s for as long as the pilot held the switch (the soak: a throttle stick
    centred, which ArduCopter's arming refuses)."""

    name = "LANDED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        if ctx.previous == "TAKEOFF" and not faulted(inp.script_state, inp.script_present):
            ctx.marks["takeoff_release"] = True
            ctx.act.statustext("SL take-off failed: release and ask again")
        return None

    def step(self, ctx: Context, inp: Inputs):
        if inp.takeoff_request and faulted(inp.script_state, inp.script_present):
            if ctx.marks.get("takeoff_refused") is None:
                ctx.marks["takeoff_refused"] = f"take-off refused: {FAULT_REFUSAL}"
                ctx.act.statustext("SL take-off refused: script fault, reboot")
        elif ctx.marks.get("takeoff_release"):
            if not inp.takeoff_request:  # let go: the next request is a new one
                ctx.marks.pop("takeoff_release")
        elif inp.takeoff_request:
            ctx.marks.pop("takeoff_refused", None)
            return ("TAKEOFF", "take-off commanded")
        return self._disarm_if_armed(ctx, inp)

    @staticmethod
    def _disarm_if_armed(ctx: Context, inp: Inputs) -> None:
        if inp.armed and inp.link_ok:  # a lost link's armed flag is stale, and a command lost
            if inp.script_present and inp.script_state in DISARMS:
                request_disarm(ctx, inp)
            else:
                request_ground_disarm(ctx, inp)
        return None
