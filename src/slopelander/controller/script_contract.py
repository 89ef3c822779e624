"""The companion's side of the on-board script's contract (docs/onboard-script.md), in one place.

The script's state numbers, its command ids, actions and parameter ranges, and :class:`ScriptClient`,
the one object that sends it requests. Every request carries a request number in COMMAND_LONG
param 7; the script echoes it in COMMAND_ACK ``result_param2`` (a MAVLink 2 extension field), and
the link's own request tracking (:meth:`Link.command` with ``request``) matches each ACK to its
request by that number: an old refresh's ACK can no longer mark a later abort accepted.
``tests/firmware/test_script_contract.py`` holds this table to the Lua script.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from slopelander.controller.link import CommandHandle, Link, LinkError

#: the contract version this companion speaks (the script's SL_VER must be at least this):
#: 2 ends the reverse thrust on a refresh, 3 ramps it down, 4 numbers every request and adds
#: SETUP, END_REVERSE, TAKEOFF_RELEASE and DISARM, 5 adds CLIMB, FAULT and FAULT_HELD, a disarm
#: only after the vehicle has been still for :data:`STILL_S`, 6 keeps a cut whose vehicle still
#: falls freely at the missed-impact bound for :data:`FALL_WAIT_S` (the companion's backstop
#: counts on it), 7 cuts on the descent reckoned from the last trusted reading through a dropout
#: or a spike within 0.3 m of the cut height, 8 reckons through a reading that stopped moving (a
#: stuck sensor) and takes only a push up the body for the impact, 9 keeps an ARMED reflex's cut
#: for 0.4 s more when it lapses within 0.15 m over the cut height (a climb would stop on the roof),
#: 10 widens that band with the square of the descent speed over 0.5 m/s and keeps the cut as
#: long as braking to rest across it takes (0.6 s at 0.5 m/s)
SCRIPT_CONTRACT = 10

CMD_ACTUATOR = 31010  # MAV_CMD_USER_1
CMD_REFLEX = 31011  # MAV_CMD_USER_2
#: the COMMAND_LONG parameter (1-based) that carries the request number
REQUEST_PARAM = 7
#: request numbers are whole numbers 1 .. 2**24 - 1: a float32 parameter holds them exactly
REQUEST_MAX = (1 << 24) - 1
G = 9.80665
#: the smallest impact threshold (m/s²): the filtered accelerometer reads ~1 g in the steady
#: descent at the cut and less while the thrust decays; 2 g leaves a full g of margin
IMPACT_MIN_MPS2 = 2 * G
#: an impact pushes up the body: its specific force's body-up share (-z, FRD) above this (m/s²)
IMPACT_UP_MPS2 = 0.0
#: the tilt (deg) within which a take-off release is asked to find the vehicle (the script
#: accepts bounds of 1..30): below ArduCopter's default ANGLE_MAX (30 deg), so the attitude
#: controller that gets the motors back can hold the attitude it starts from
TAKEOFF_RELEASE_TILT_DEG = 25.0


#: the spin-down of the rotors and one 20 Hz range sample, added to the free fall (ms), as the script
THRUST_DECAY_MS, RANGE_PERIOD_MS = 100, 50
#: the impact rule's rise (a reading a threshold less 1 g above the lowest since the cut) counts only
#: this long (s) after the cut, the script's RISE_AFTER_MS: the rotors' time constant, by which their
#: thrust and vibration are down to 14 %; before it a trough and the next crest of the hover's
#: vibration read as a rise (issue 40), and only the threshold itself (and the range) can fire
RISE_AFTER_S = 0.05
#: how much longer (s) than :func:`missed_impact_s` a cut may last: a vehicle still falling freely
#: at that bound with the range near (a low reading that lasted) keeps its cut and waits this long
#: for the impact (the script's MS.FALL_WAIT)
FALL_WAIT_S = 0.5


def missed_impact_s(cut_m: float, descent_mps: float) -> float:
    """How long (s) after the cut the script waits for an impact before it judges the cut (its
    ``missed_impact_ms``): the free fall from the cut height at the descent speed, plus the rotors'
    spin-down and a range sample. ``tests/firmware/test_script_contract.py`` holds the two equal."""
    fall_s = ((descent_mps**2 + 2 * G * cut_m) ** 0.5 - descent_mps) / G
    return (int(fall_s * 1000 + THRUST_DECAY_MS + RANGE_PERIOD_MS + 0.5)) / 1000.0


class ScriptState(IntEnum):
    """The script's states, as it announces them in NAMED_VALUE_FLOAT ``SL_STATE``."""

    IDLE = 0  # released: the autopilot's mixer drives the motors
    STOP = 1  # commanded stop (actuator)
    REVERSE = 2  # commanded reverse thrust (actuator)
    ARMED = 10  # reflex armed, watching the range
    CUT = 11  # motors stopped at the cut height, watching for the impact
    RVT = 12  # reflex reverse thrust after the impact
    HOLD = 13  # on the ground, motors held stopped
    CLIMB = 14  # an ARMED reflex lapsed (the companion silent): the script climbs in GUIDED, then IDLE
    ESTOP = 20  # the pilot's emergency stop: everything released
    FAULT = 30  # the script's update raised: reflex gone for good, motors the autopilot's (an ARMED
    #           descent stopped: climbing); only DISARM and ABORT (ends the climb) answered
    FAULT_HELD = 31  # raised from the cut on: motors held stopped until disarmed (still) or e-stop


def state_name(state: int | None) -> str:
    """The script state's name (its number when the script reports one this side does not know)."""
    try:
        return ScriptState(state).name
    except ValueError:
        return str(state)


#: the script's landing sequence: from the cut on, it holds the motors and refuses an abort or a
#: release; only a disarm, a level take-off release, the emergency stop or leaving the roof end it
LANDING = frozenset({ScriptState.CUT, ScriptState.RVT, ScriptState.HOLD})
#: the script failed (contract 5): it will never cut or reverse again until the autopilot restarts
#: it. FAULT_HELD still holds the motors stopped on the roof and answers DISARM
FAULTS = frozenset({ScriptState.FAULT, ScriptState.FAULT_HELD})
#: how long (s) the vehicle must read still (body rates under 5 deg/s, speed at most 0.10 m/s) before
#: the script disarms it, on a DISARM or by itself (contract 5): ArduCopter's land detector's time
STILL_S = 1.0


class Actuator(IntEnum):
    """``CMD_ACTUATOR`` param 1."""

    RELEASE = 0
    STOP = 1
    REVERSE = 2


class Reflex(IntEnum):
    """``CMD_REFLEX`` param 1."""

    ABORT = 0
    ARM = 1  # also the refresh
    END_REVERSE = 2
    SETUP = 3
    TAKEOFF_RELEASE = 4
    DISARM = 5


_ARM_LIMITS = {
    2: (0.10, 2.00),  # cut height, m
    3: (IMPACT_MIN_MPS2, 200.0),  # impact threshold, m/s²
    4: (0.0, 100.0),  # reverse thrust, %
    5: (0.0, 5000.0),  # reverse-thrust duration, ms
    6: (100.0, 10000.0),  # validity, ms
}
#: (command, action) -> {param (1-based): (low, high)}: the ranges the script accepts, inclusive;
#: outside them it answers DENIED. Param 7 is always the request number (1..REQUEST_MAX).
PARAM_LIMITS: dict[tuple[int, int], dict[int, tuple[float, float]]] = {
    (CMD_ACTUATOR, Actuator.RELEASE): {},
    (CMD_ACTUATOR, Actuator.STOP): {2: (0.0, 100.0), 3: (20.0, 5000.0)},
    (CMD_ACTUATOR, Actuator.REVERSE): {2: (0.0, 100.0), 3: (20.0, 5000.0)},
    (CMD_REFLEX, Reflex.ABORT): {},
    (CMD_REFLEX, Reflex.ARM): _ARM_LIMITS,
    (CMD_REFLEX, Reflex.END_REVERSE): _ARM_LIMITS,
    (CMD_REFLEX, Reflex.SETUP): {2: (0.0, 3000.0), 3: (0.1, 3.0)},  # ramp ms, descent m/s
    (CMD_REFLEX, Reflex.TAKEOFF_RELEASE): {2: (1.0, 30.0)},  # tilt bound, deg
    (CMD_REFLEX, Reflex.DISARM): {},
}


@dataclass
class ScriptRequest:
    """One request to the script: poll ``state`` ('pending', 'accepted', 'rejected', 'unanswered').

    A view of the link's :class:`~slopelander.controller.link.CommandHandle` for it (sent with the
    request number, so only the ACK echoing that number in ``result_param2`` answers it), plus
    the script's STATUSTEXT reason for a refusal."""

    number: int
    kind: str
    handle: CommandHandle
    #: the script's STATUSTEXT reason for a refusal ("SL: ..." without the prefix), when it came
    reason: str | None = None

    @property
    def command(self) -> int:
        return self.handle.command

    @property
    def params(self) -> tuple[float, ...]:
        return self.handle.params

    @property
    def result(self) -> int | None:
        """The ACK's MAV_RESULT (None until answered)."""
        return self.handle.result

    @property
    def tries(self) -> int:
        return self.handle.tries

    @property
    def state(self) -> str:
        s = self.handle.state
        return "unanswered" if s == "timeout" else s

    @property
    def done(self) -> bool:
        """Answered, or out of tries."""
        return self.handle.done

    @property
    def ok(self) -> bool:
        """The script accepted it."""
        return self.handle.ok


class ScriptClient:
    """Sends the script's requests through the link, each with its own request number.

    The link (:meth:`Link.command` with ``request``) sends, re-sends (same number) every
    ``timeout_s`` until answered, at most ``retries`` times, and matches each COMMAND_ACK to its
    request by the number the script echoes in ``result_param2``: one ACK-matching path for every
    command the companion sends. Any number of requests may be in flight at once, of any kind.
    This client numbers them, keeps them by number and kind, and attaches the script's reason to a
    refusal (the STATUSTEXT the script sends right after its ACK)."""

    def __init__(self, link: Link, retries: int = 2, timeout_s: float = 0.5) -> None:
        self.link = link
        self.retries = int(retries)
        self.timeout_s = float(timeout_s)
        self._next = 1
        self._open: list[ScriptRequest] = []  # sent, not yet seen answered
        #: every request by number, the newest ``KEEP`` of them
        self.requests: dict[int, ScriptRequest] = {}
        #: the newest request of each kind ('arm', 'abort', 'disarm', ...)
        self.last: dict[str, ScriptRequest] = {}
        self._refused: ScriptRequest | None = None  # the newest refusal still waiting for its reason
        link.add_listener(self._on_message)

    KEEP = 256

    # ------------------------------------------------------------------ requests
    def setup(self, ramp_ms: float, descent_mps: float) -> ScriptRequest:
        """The landing's settings the reflex needs before ARM: the reverse-thrust ramp (ms) and the
        descent rate (m/s) that bounds the wait for an impact after the cut."""
        return self._send("setup", CMD_REFLEX, Reflex.SETUP, ramp_ms, descent_mps)

    def arm(
        self, cut_m: float, impact_mps2: float, pct: float, reverse_ms: float, validity_ms: float
    ) -> ScriptRequest:
        """Arm the reflex, or refresh it (in CUT and HOLD a refresh only renews the validity; in
        RVT it also sets the reverse-thrust duration, counted from the impact)."""
        return self._send("arm", CMD_REFLEX, Reflex.ARM, cut_m, impact_mps2, pct, reverse_ms, validity_ms)

    def end_reverse(self, cut_m: float, impact_mps2: float, pct: float, validity_ms: float) -> ScriptRequest:
        """End the reverse thrust now (it ramps down, then HOLD); renews the validity like a refresh."""
        return self._send("end", CMD_REFLEX, Reflex.END_REVERSE, cut_m, impact_mps2, pct, 0, validity_ms)

    def abort(self) -> ScriptRequest:
        """Abort an armed reflex (refused from the cut on: the motors stay held)."""
        return self._send("abort", CMD_REFLEX, Reflex.ABORT)

    def release_for_takeoff(self, max_tilt_deg: float = TAKEOFF_RELEASE_TILT_DEG) -> ScriptRequest:
        """Give the motors back for a take-off; a held vehicle only within ``max_tilt_deg`` of level."""
        return self._send("takeoff_release", CMD_REFLEX, Reflex.TAKEOFF_RELEASE, max_tilt_deg)

    def disarm(self) -> ScriptRequest:
        """Ask the script to disarm: it does while it holds the motors stopped and the vehicle is still."""
        return self._send("disarm", CMD_REFLEX, Reflex.DISARM)

    def release(self) -> ScriptRequest:
        """Give commanded outputs back to the autopilot (refused from the cut on)."""
        return self._send("release", CMD_ACTUATOR, Actuator.RELEASE)

    def stop(self, validity_ms: float) -> ScriptRequest:
        return self._send("stop", CMD_ACTUATOR, Actuator.STOP, 0, validity_ms)

    def reverse(self, pct: float, validity_ms: float) -> ScriptRequest:
        return self._send("reverse", CMD_ACTUATOR, Actuator.REVERSE, pct, validity_ms)

    # ------------------------------------------------------------------ answers
    def status(self, number: int) -> str:
        """'pending', 'accepted', 'rejected' or 'unanswered' for request ``number`` ('unknown'
        for a number never sent, or one too old to be kept)."""
        r = self.requests.get(number)
        return "unknown" if r is None else r.state

    def poll(self) -> None:
        """Read what has come and re-send what is due (the link's poll: it owns the retries)."""
        self.link.poll()
        self._note_answers()

    # ------------------------------------------------------------------ internals
    def _send(self, kind: str, command: int, action: int, *params: float) -> ScriptRequest:
        if self.link.info is None:
            raise LinkError("no autopilot found yet: wait_autopilot() before sending commands")
        number = self._next
        self._next = 1 if self._next >= REQUEST_MAX else self._next + 1
        p = [float(action), *(float(x) for x in params)]
        p += [0.0] * (REQUEST_PARAM - 1 - len(p))
        h = self.link.command(
            command, *p, float(number), retries=self.retries, timeout_s=self.timeout_s, request=number
        )
        r = ScriptRequest(number, kind, h)
        self.requests[number] = r
        if len(self.requests) > self.KEEP:
            del self.requests[next(iter(self.requests))]
        self.last[kind] = r
        self._open.append(r)
        return r

    def _note_answers(self) -> None:
        """The requests the link has seen answered since the last look: the newest refusal waits
        for the script's reason; an acceptance after it means that reason is not coming."""
        still = []
        for r in self._open:
            if not r.done:
                still.append(r)
            elif r.state == "rejected":
                self._refused = r
            elif r.ok:
                self._refused = None
        self._open = still

    def _on_message(self, msg) -> None:
        # the link calls its listeners before it applies a COMMAND_ACK: an ACK's effect is seen
        # here from the next message on, which is where its STATUSTEXT reason comes
        self._note_answers()
        if msg.get_type() == "STATUSTEXT" and self._refused is not None:
            text = msg.text.rstrip("\x00") if isinstance(msg.text, str) else ""
            if text.startswith("SL: "):
                self._refused.reason = text[4:]
                self._refused = None
