"""The landing state machine: failsafe policy first, then the current state's own step.

Every change of state goes through :meth:`Machine.transition`, which calls leave/enter, logs,
appends one JSON line to the record and tells the ground station by STATUSTEXT. The failure
policy it applies is the table in docs/failsafes.md.
"""

from __future__ import annotations

import json
import logging
from typing import IO

from slopelander.controller.script_contract import LANDING, ScriptState
from slopelander.controller.script_rules import MOTORS_HELD, script_move
from slopelander.controller.states.aborted import Aborted
from slopelander.controller.states.armed import Armed
from slopelander.controller.states.base import Context, Inputs, State
from slopelander.controller.states.checks import Checks
from slopelander.controller.states.cut import Cut
from slopelander.controller.states.descend import Descend
from slopelander.controller.states.estop import Estop
from slopelander.controller.states.landed import Landed
from slopelander.controller.states.legs_wait import LegsWait
from slopelander.controller.states.link_lost import LinkLost
from slopelander.controller.states.preset import Preset
from slopelander.controller.states.ready import Ready
from slopelander.controller.states.reset import Reset
from slopelander.controller.states.reverse import Reverse
from slopelander.controller.states.settled import Settled, reads_in_the_air
from slopelander.controller.states.takeoff import Takeoff

log = logging.getLogger("slopelander.controller")

STATES: dict[str, type[State]] = {
    s.name: s
    for s in (
        Preset,
        LegsWait,
        Checks,
        Descend,
        Armed,
        Cut,
        Reverse,
        Settled,
        Landed,
        Takeoff,
        Reset,
        Ready,
        Aborted,
        Estop,
        LinkLost,
    )
}
PRE_CONTACT = ("PRESET", "LEGS_WAIT", "CHECKS", "DESCEND", "ARMED")
#: the script's reports that say the vehicle met the roof
CONTACT = (ScriptState.RVT, ScriptState.HOLD, ScriptState.FAULT_HELD)
LINK_EXEMPT = ("LANDED", "ABORTED", "ESTOP", "LINK_LOST", "READY")


def failsafe(state: State, inp: Inputs) -> tuple[str, str] | None:
    """The policy of docs/failsafes.md: which failure moves the machine where, in this state."""
    name = state.name
    if inp.estop and name != "ESTOP":
        return ("ESTOP", "emergency stop")
    if not inp.link_ok and name not in LINK_EXEMPT:
        why = f" ({inp.link_lost_why})" if inp.link_lost_why else ""
        return ("LINK_LOST", f"link to the autopilot lost{why}")
    if state.airborne_descent and inp.script_present and inp.script_state in LANDING:
        # The script cut the motors before this step saw it (a slow companion reads the cut and
        # the range below the sensor's minimum in one batch): aborting now would hand a falling
        # vehicle back to the autopilot. The state's own step moves on to CUT, whose row applies.
        return None
    # the script's own word (controller/script_rules.py): a fault, its climb, its silence
    move = script_move(name, inp.script_state, inp.script_present, inp.armed)
    if move is not None:
        return move
    if name in PRE_CONTACT and inp.legs_fault:
        return ("ABORTED", f"leg failure: {inp.legs_fault}")
    if state.airborne_descent:
        if inp.mode != "GUIDED":
            return ("ABORTED", f"pilot changed mode to {inp.mode}")
        if not inp.range_valid:
            return ("ABORTED", "range invalid or missing")
    return None


class Machine:
    """Runs the sequence; feed it :class:`Inputs` with :meth:`step`."""

    def __init__(self, ctx: Context, record: IO[str] | None = None, start: str = "PRESET") -> None:
        self.ctx = ctx
        self.record = record
        self.history: list[dict] = []
        self.state: State = STATES[start]()
        self._started = False
        self._start = start

    @property
    def name(self) -> str:
        return self.state.name

    def held_on_the_roof(self, inp: Inputs) -> bool:
        """Whether this landing has met the roof (an impact, or the script's landing sequence
        reported after the cut) and the script still holds the motors of an armed vehicle, or has
        gone silent there with the range not reading it in the air (it may hold them still;
        SETTLED judges a silent script as one, with the forced disarm at rest:
        ``Settled.without_script``, not LOITER on the roof). The
        script's own RVT or HOLD is that evidence too: a vehicle that came down while the link was
        out is on the roof before any state of this machine marked an impact. It is asked outside
        a step too (the runner's interrupt and time-out), so it notes the contact in ``inp``
        itself."""
        self._note_contact(inp)
        met = self.ctx.marks.get("impact") is not None
        if inp.script_present:
            held = inp.script_state in MOTORS_HELD
        else:  # silent: on the roof unless the range reads it in the air (as SETTLED judges it)
            held = not reads_in_the_air(self.ctx.cfg, inp)
        return self._started and met and inp.armed and held

    def _note_contact(self, inp: Inputs) -> None:
        """The script's RVT, HOLD or FAULT_HELD is the contact, kept for the landing: a later (stale
        or reordered) report does not undo it. A take-off clears the mark (states/takeoff.py)."""
        if inp.script_present and inp.script_state in CONTACT:
            self.ctx.marks.setdefault("impact", inp.t)

    def transition(self, new: str, reason: str, inp: Inputs) -> None:
        """Leave the current state, enter ``new``; a refused enter aborts (the reason recorded).

        After contact, while the script holds the motors of an armed vehicle, nothing hands the
        vehicle to the autopilot: an abort from any cause (a timeout, a state's own judgement)
        becomes SETTLED, which keeps the motors held and has the vehicle disarmed at rest; the
        ways out are a disarm, the pilot's emergency stop or a commanded take-off."""
        if new == "ABORTED" and self.held_on_the_roof(inp):
            reason = f"{reason}; after contact, motors held: judged on the roof, not handed back"
            if self._started and self.state.name == "SETTLED":
                log.info("SETTLED stays: %s", reason)
                return
            new = "SETTLED"
        old = self.state.name if self._started else None
        if self._started:
            self.state.leave(self.ctx, inp)
        self._started = True
        self.state = STATES[new]()
        self.ctx.entered_at = inp.t
        self.ctx.previous = old
        entry = {"t": round(inp.t, 6), "from": old, "to": new, "reason": reason}
        self.history.append(entry)
        log.info("%s -> %s: %s", old, new, reason)
        if self.record is not None:
            self.record.write(json.dumps(entry) + "\n")
            self.record.flush()
        if inp.link_ok:
            self.ctx.act.statustext(f"SL {new}: {reason}"[:50])
        refused = self.state.enter(self.ctx, inp)
        if refused is not None and new != "ABORTED":
            self.transition(self.state.refused_to, f"{new} refused: {refused}", inp)

    def step(self, inp: Inputs) -> str:
        """One control step; returns the state name after it."""
        self._note_contact(inp)
        if not self._started:
            self.transition(self._start, "landing requested", inp)
        for _ in range(len(STATES)):  # a chain of immediate transitions settles within one step
            move = failsafe(self.state, inp) or self.state.step(self.ctx, inp)
            if move is None or move[0] == self.state.name:
                break
            self.transition(move[0], move[1], inp)
        return self.state.name
