"""What the companion does on each report of the on-board script, in each phase of a landing: one
table (docs/failsafes.md, "The on-board script's reports").

The script's state is read here only. A script not heard for a second (``Inputs.script_present``
false) reads SILENT, never IDLE: IDLE means "released, the autopilot flies", which a dead script
after the cut is not (its overrides lapse within 250 ms and the mixer gets the motors). The
states of the machine ask :func:`reading` and the sets below; :func:`script_move` is the part of
the failure policy that moves the machine on the script's word alone.
"""

from __future__ import annotations

from slopelander.controller.script_contract import FAULTS, LANDING, ScriptState, state_name

S = ScriptState

#: the reading of a script not heard for a second (docs/failsafes.md, "Script missing")
SILENT = "SILENT"
#: the reading of a number this companion does not know (a newer contract's state)
UNKNOWN = "UNKNOWN"

#: the script holds the reflex: armed, or already past the cut
REFLEX_HELD = frozenset({S.ARMED}) | LANDING
#: the script cut the motors and holds them: its landing sequence, or a fault after the cut
MOTORS_HELD = LANDING | {S.FAULT_HELD}
#: the script let go of the motors: the autopilot's mixer drives them
LET_GO = frozenset({S.IDLE, S.STOP, S.REVERSE})
#: the script accepts a DISARM in these (docs/onboard-script.md, action 5)
DISARMS = frozenset({S.HOLD, S.STOP, S.FAULT_HELD})
#: the script stops a descent by itself (it climbs): its ARMED reflex lapsed, or it failed there
STOPS_DESCENT = frozenset({S.CLIMB, S.FAULT})
#: readings with no reflex and no held motors: a dead or failed script
GONE = frozenset({SILENT, "FAULT"})

#: why nothing is flown with a faulted script: it refuses everything but DISARM and ABORT until the
#: autopilot restarts it (a reboot), so it would neither cut nor release for a take-off
FAULT_REFUSAL = "on-board script fault: reboot the autopilot"

#: the companion's states by phase of the landing
BEFORE_DESCENT = ("PRESET", "LEGS_WAIT", "CHECKS")
DESCENT = ("DESCEND", "ARMED")
AFTER_CUT = ("CUT", "REVERSE", "SETTLED")

_FAULT_HELD = ("SETTLED", "on-board script fault after the cut: motors held, disarming once still")
_GONE_AFTER_CUT = "on-board script {what} after the cut: judged by the range (SETTLED)"

#: (phase, reading) -> (next state, reason). Readings not in it are each state's own business
#: (ARMED waits for ARMED, CUT for RVT/HOLD, SETTLED notices a let-go, ...). Why each row:
#:  * FAULT_HELD anywhere in a landing: the motors are held stopped on the roof; SETTLED keeps
#:    asking DISARM (the script disarms once still) and never hands the vehicle to LOITER.
#:  * CLIMB or FAULT before contact: the script has no reflex any more and is stopping the
#:    descent itself; the landing is stopped (ABORTED: climb setpoint, LOITER), never re-armed.
#:  * SILENT before contact: no reflex to cut; ABORTED.
#:  * SILENT or FAULT after the cut: nobody holds the motors; SETTLED decides by the range
#:    (in the air: ABORTED, the autopilot flies; on the roof: the companion disarms).
RULES: dict[tuple[tuple[str, ...], str], tuple[str, str]] = {
    (BEFORE_DESCENT, "FAULT"): ("ABORTED", "on-board script fault: no reflex for this landing"),
    (BEFORE_DESCENT, "CLIMB"): ("ABORTED", "on-board reflex lapsed (script CLIMB)"),
    (BEFORE_DESCENT, "FAULT_HELD"): _FAULT_HELD,
    (DESCENT, SILENT): ("ABORTED", "on-board script silent"),
    (DESCENT, "FAULT"): ("ABORTED", "on-board script fault: it stops the descent, landing stopped"),
    (DESCENT, "CLIMB"): ("ABORTED", "on-board reflex lapsed, the script climbs: landing stopped"),
    (DESCENT, UNKNOWN): ("ABORTED", "on-board script in a state this companion does not know"),
    (DESCENT, "FAULT_HELD"): _FAULT_HELD,
    (AFTER_CUT, SILENT): ("SETTLED", _GONE_AFTER_CUT.format(what="silent")),
    (AFTER_CUT, "FAULT"): ("SETTLED", _GONE_AFTER_CUT.format(what="fault")),
    (AFTER_CUT, "FAULT_HELD"): _FAULT_HELD,
    (("TAKEOFF", "RESET"), "FAULT_HELD"): _FAULT_HELD,
}


def reading(state: int, present: bool) -> str:
    """The script's report as the table reads it: SILENT when not heard, else its state's name
    (UNKNOWN for a number this side does not know)."""
    if not present:
        return SILENT
    name = state_name(state)
    return UNKNOWN if name == str(state) else name


def faulted(state: int, present: bool) -> bool:
    """The script reports a fault (FAULT or FAULT_HELD): kept until the autopilot restarts it."""
    return present and state in FAULTS


def script_move(companion_state: str, state: int, present: bool, armed: bool) -> tuple[str, str] | None:
    """The move :data:`RULES` asks for in ``companion_state``, or None. A held vehicle that is
    disarmed is landed already: the HEARTBEAT's word wins, and LANDED is not left for SETTLED."""
    r = reading(state, present)
    if r == "FAULT_HELD" and (not armed or companion_state == "SETTLED"):
        return None
    for (phase, what), move in RULES.items():
        if what == r and companion_state in phase:
            return None if move[0] == companion_state else move
    return None
