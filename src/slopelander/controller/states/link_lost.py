"""LINK_LOST: nothing can be sent, so safety rests on the autopilot's and the script's own timeouts."""

from __future__ import annotations

from slopelander.controller.script_rules import MOTORS_HELD
from slopelander.controller.states.base import Context, Inputs, State

#: states after contact: the vehicle is on the roof and the script owns the motors
AFTER_CONTACT = ("CUT", "REVERSE", "SETTLED")


class LinkLost(State):
    """On board: GUID_TIMEOUT stops the descent, the reflex validity lapses, a HOLD disarms when its
    validity lapses. When the link returns: a take-off lost with the vehicle still below the clear
    height goes on (TAKEOFF) if it is armed and is LANDED if not; a landing lost before contact is
    aborted to LOITER; one
    lost after contact is judged as it lies (SETTLED: disarmed at rest, handed to the pilot armed if
    it slides), because releasing a script that is still reversing or holding the motors on a roof
    and asking a grounded vehicle for LOITER is no safer than finishing the landing."""

    name = "LINK_LOST"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.marks["lost_in"] = ctx.previous
        return None

    def step(self, ctx: Context, inp: Inputs):
        if not inp.link_ok:
            return None
        # lost before contact but the script reports its landing sequence: the vehicle came down
        # while the link was out, and a tilted vehicle on a roof is not handed to LOITER
        landed_meanwhile = inp.script_present and inp.script_state in MOTORS_HELD
        if ctx.marks.get("lost_in") == "TAKEOFF" and not landed_meanwhile:
            # lost during the take-off: a vehicle still near the roof is not handed to LOITER
            # armed there (seen: armed on the roof in LOITER, it slid 20 m down it). Disarmed
            # (the arm never came), it is landed; armed, the take-off asked for goes on.
            clear = inp.range_valid and inp.range_m >= ctx.cfg["takeoff.clear_height_m"]
            if not clear and not inp.armed:
                return ("LANDED", "link back during the take-off: disarmed on the roof")
            if not clear:
                return ("TAKEOFF", "link back during the take-off, near the roof: taking off again")
        if ctx.marks.get("lost_in") in AFTER_CONTACT or landed_meanwhile:
            if not inp.armed:
                return ("LANDED", "link back: the script disarmed on the ground")
            if landed_meanwhile:
                ctx.marks.setdefault("impact", inp.t)
            return ("SETTLED", "link back after contact: judging rest")
        return ("ABORTED", "link back: aborting the landing")
