"""The companion's MAVLink link to the autopilot: non-blocking, polled by the state machine.

One :class:`Link` owns the connection. :meth:`Link.poll` drains every waiting message without
blocking, keeps the vehicle clock, sends the companion's heartbeat (1 Hz) and, to a lock-stepped
simulator only, the TIMESYNC echo it waits on; re-sends commands that were not acknowledged and
expires the ones that ran out of tries. Commands return a :class:`CommandHandle` that the caller
polls instead of waiting; every command is tracked until its own answer (see :meth:`Link.command`).
It measures each requested stream's delivered rate in vehicle time (:func:`stream_refusal`) and
notices an autopilot that rebooted under it (:attr:`Link.rebooted`).
"""

from __future__ import annotations

import math
import os
import select
import struct
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

# The MAVLink 2 message set, whatever was imported before: only it has COMMAND_ACK.result_param2,
# the request number the on-board script echoes (a MAVLink 1 peer is still understood).
os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

from slopelander.controller.clock import VehicleClock
from slopelander.controller.frames import FrameFilter
from slopelander.errors import SlopelanderError

mavlink = mavutil.mavlink

COMPANION_COMPONENT = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER
HEARTBEAT_PERIOD_S = 1.0
#: ArduPilot sends its HEARTBEAT at 1 Hz on every MAVLink channel (GCS_MAVLINK::update_send)
AUTOPILOT_HEARTBEAT_S = 1.0
TIMESYNC_PERIOD_S = 0.02
#: the lock-step probe (see :meth:`Link._timesync`): a vehicle that, after the one echo, moves its
#: clock on and then falls silent for ``PROBE_STALL_S`` of local time waits for the echo; one whose
#: clock runs on ``PROBE_FREE_S`` past it does not. Undecided after ``PROBE_AGAIN_S``: probe again.
PROBE_FREE_S = 1.0
PROBE_STALL_S = 0.3
PROBE_AGAIN_S = 2.0
#: a reboot: this many messages in a row stamped more than ``REBOOT_BACK_S`` before the newest
#: vehicle time (one reordered or late frame is not; a relay holds back one frame at a time)
REBOOT_BACK_S = 1.0
REBOOT_RUN = 5
#: the shortest stretch of vehicle time a stream's delivered rate is measured over, and the longest
STREAM_MIN_SPAN_S = 0.5
STREAM_WINDOW_S = 2.0
SCRIPT_SILENT_S = 1.0  # vehicle seconds without SL_STATE: the script is silent
SCRIPT_ANNOUNCE_WAIT_S = 1.5  # local s: the script's SL_VER comes once a second
#: a jump in the newest vehicle time larger than this (s) is a telemetry gap (a 200 Hz IMU stream
#: normally advances it by 5 ms): ages of what the link holds are counted from where it resumed
GAP_S = 0.1
# Messages that carry the autopilot's time, and the field holding it.
_USEC_FIELDS = {
    "SYSTEM_TIME": "time_boot_ms",
    "RAW_IMU": "time_usec",
    "HIGHRES_IMU": "time_usec",
    "ATTITUDE": "time_boot_ms",
    "LOCAL_POSITION_NED": "time_boot_ms",
    "SERVO_OUTPUT_RAW": "time_usec",
    "DISTANCE_SENSOR": "time_boot_ms",
    "NAMED_VALUE_FLOAT": "time_boot_ms",
    "RC_CHANNELS": "time_boot_ms",
}


#: what a landing reads from the autopilot; everything else can be dropped before decoding
LANDING_MESSAGES = frozenset(
    {
        "HEARTBEAT",
        "COMMAND_ACK",
        "STATUSTEXT",
        "AUTOPILOT_VERSION",
        "SYSTEM_TIME",
        "NAMED_VALUE_FLOAT",
        "RAW_IMU",
        "DISTANCE_SENSOR",
        "LOCAL_POSITION_NED",
        "ATTITUDE",
        "RC_CHANNELS",
    }
)
#: messages every one of which a reader needs, not only the newest (the impact detector reads every
#: IMU sample, however seldom the landing loop wakes): the link keeps the last few of each
#: and the attitude a range reading was taken with is looked up among the recent ATTITUDEs
KEEP_RECENT = ("RAW_IMU", "ATTITUDE")  # what the landing reads; HIGHRES_IMU is not
RECENT_LEN = 64
#: the largest read from the link per call (a UDP read returns one datagram whatever this is)
RECV_BYTES = 4096


def _stamp_usec(msg, fld: str) -> int | None:
    """The autopilot's time on ``msg`` in microseconds (None: not stamped, 0 or less)."""
    v = int(getattr(msg, fld))
    if v <= 0:
        return None
    return v if fld == "time_usec" else v * 1000


def message_ids(names) -> frozenset[int]:
    """MAVLink message ids for message names; an unknown name is a :class:`LinkError`."""
    ids = set()
    for name in names:
        msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}", None)
        if not isinstance(msg_id, int):
            raise LinkError(f"unknown MAVLink message name {name!r} in the messages to decode")
        ids.add(msg_id)
    return frozenset(ids)


class LinkError(SlopelanderError):
    """The link cannot be opened or used (bad connection string, no autopilot)."""


@dataclass
class CommandHandle:
    """One COMMAND_LONG: poll ``state`` ('pending', 'accepted', 'rejected', 'timeout').

    ``request``: a number the autopilot echoes in COMMAND_ACK.result_param2 (the on-board script
    does), so the ACK is matched to this request alone. Without one, the ACK carries nothing but
    the command id (ArduPilot's ACK of SET_MESSAGE_INTERVAL echoes neither the message id nor the
    interval), so requests of the same id are sent one at a time, in order: ``tries`` stays 0
    while one is queued behind another."""

    command: int
    params: tuple[float, ...]
    retries: int
    timeout_s: float
    request: int | None = None
    state: str = "pending"
    result: int | None = None
    tries: int = 0
    sent_at: float = 0.0

    @property
    def done(self) -> bool:
        """Whether an answer (or the final timeout) has arrived."""
        return self.state != "pending"

    @property
    def ok(self) -> bool:
        """Whether the autopilot accepted the command."""
        return self.state == "accepted"


@dataclass
class AutopilotInfo:
    """What the companion found at the other end of the link."""

    system: int
    component: int
    vehicle_type: int
    autopilot: int
    firmware: str = "unknown"
    script_version: float | None = None

    def describe(self) -> str:
        """One line for the pilot."""
        vt = mavlink.enums["MAV_TYPE"].get(self.vehicle_type)
        ap = mavlink.enums["MAV_AUTOPILOT"].get(self.autopilot)
        # "not heard", not "absent": a script announces its version once a second, and a line
        # printed before that would call a running script missing (CHECKS refuses a silent one)
        script = "not heard" if self.script_version is None else f"v{self.script_version:g}"
        return (
            f"system {self.system} component {self.component}: "
            f"{vt.name if vt else self.vehicle_type}, {ap.name if ap else self.autopilot}, "
            f"firmware {self.firmware}, on-board script {script}"
        )


@dataclass
class _Stream:
    """One requested stream: what was asked, since when (vehicle s), the stamps delivered since."""

    name: str
    hz: float
    since: float
    stamps: deque = field(default_factory=lambda: deque(maxlen=1024))


@dataclass
class _Rate:
    """Arrival rate of one message type over a sliding window of local time."""

    stamps: deque = field(default_factory=lambda: deque(maxlen=400))

    def add(self, t: float) -> None:
        self.stamps.append(t)

    def hz(self, now: float, window: float = 2.0) -> float:
        n = sum(1 for s in self.stamps if now - s <= window)
        return n / window


class Link:
    """A polled MAVLink connection to one autopilot.

    ``url`` is any pymavlink connection string (``udpin:0.0.0.0:14550``, ``tcp:host:5760``,
    ``/dev/ttyACM0,921600``). :attr:`lost` becomes true after ``link_loss_s`` with nothing from the
    autopilot (local time), with its messages but ``heartbeats_missed`` of its 1 Hz HEARTBEATs
    missed (vehicle time), or once it rebooted.
    ``decode``: the message names to decode (e.g. :data:`LANDING_MESSAGES`); frames of any other
    message are dropped unread (see :mod:`slopelander.controller.frames`). None decodes everything
    through pymavlink's own reader.
    """

    def __init__(
        self,
        url: str,
        *,
        link_loss_s: float = 1.5,
        heartbeats_missed: int = 3,
        monotonic: Callable[[], float] = time.monotonic,
        decode: Iterable[str] | None = None,
    ) -> None:
        if not isinstance(url, str) or not url.strip():
            raise LinkError("connection string is empty (expected e.g. udpin:0.0.0.0:14550)")
        if not (link_loss_s > 0 and math.isfinite(link_loss_s)):
            raise LinkError(f"link_loss_s must be a positive number of seconds, got {link_loss_s!r}")
        whole = isinstance(heartbeats_missed, int) and not isinstance(heartbeats_missed, bool)
        if not whole or heartbeats_missed < 1:
            raise LinkError(f"heartbeats_missed must be a whole number >= 1, got {heartbeats_missed!r}")
        self.filter = None if decode is None else FrameFilter(message_ids(decode))
        try:
            self.conn = mavutil.mavlink_connection(
                url,
                source_system=1,
                source_component=COMPANION_COMPONENT,
                dialect="ardupilotmega",
                autoreconnect=True,
            )
        except Exception as exc:  # pymavlink raises many types for a bad string or device
            raise LinkError(f"cannot open MAVLink connection {url!r}: {exc}") from exc
        self.monotonic = monotonic
        self.clock = VehicleClock(monotonic)
        self.link_loss_s = link_loss_s
        self.heartbeats_missed = heartbeats_missed
        self.info: AutopilotInfo | None = None
        self.last: dict[str, object] = {}
        self.statustext: deque[str] = deque(maxlen=50)
        self._rates: dict[str, _Rate] = {}
        self._commands: list[CommandHandle] = []
        self._last_heartbeat_rx: float | None = None
        self._last_heartbeat_vt: float | None = None  # vehicle time of the newest HEARTBEAT
        self._last_rx: float | None = None  # local time of the newest message from the autopilot
        #: local time of the newest read that found the link drained: silence is judged up to it,
        #: so a companion that stalls (a long garbage collection, a starved process) between two
        #: reads does not take its own pause for the autopilot's silence
        self._looked_at: float | None = None
        self._last_heartbeat_tx = -math.inf
        self._last_timesync_usec = 0
        #: whether the vehicle waits for the companion's TIMESYNC echo (None: not known yet)
        self.lockstep: bool | None = None
        self._probe: tuple[int, float] | None = None  # (vehicle us, local s) of the probe's echo
        self.timesync_sent = 0
        #: the autopilot rebooted under the link (its clock went back): lost for this landing
        self.rebooted = False
        self.reboot_note: str | None = None
        self._behind = 0
        #: requested streams by message name (see :meth:`delivered_hz`)
        self.streams: dict[str, _Stream] = {}
        self._script_seen_at: float | None = None
        self.script_state: int | None = None
        self._script_stamp = -1  # vehicle time (us) of the SL_STATE in script_state
        #: vehicle time (us) of the message in ``last`` per type
        self._stamps: dict[str, int] = {}
        #: vehicle time at which telemetry resumed after the last gap (-inf: none yet)
        self.resumed_at = -math.inf
        self._listeners: list[Callable[[object], None]] = []
        self._recent: dict[str, deque] = {k: deque(maxlen=RECENT_LEN) for k in KEEP_RECENT}
        #: messages received per type since the link opened (what :meth:`since` counts from)
        self.received: dict[str, int] = {}

    # ---------------------------------------------------------------- receiving
    def set_decode(self, names: Iterable[str] | None) -> None:
        """Decode only these messages from now on (None: all, through pymavlink's own reader)."""
        self.filter = None if names is None else FrameFilter(message_ids(names))

    def add_listener(self, fn: Callable[[object], None]) -> None:
        """Call ``fn(msg)`` for every message from the autopilot (e.g. the impact detector)."""
        self._listeners.append(fn)

    def since(self, mtype: str, count: int) -> tuple[list, int]:
        """The messages of ``mtype`` (one of :data:`KEEP_RECENT`) received after the first ``count``,
        oldest first, and the new count: at most :data:`RECENT_LEN` of them, the newest."""
        total = self.received.get(mtype, 0)
        new = total - count
        if new <= 0:
            return [], total
        recent = self._recent[mtype]
        return list(recent)[-min(new, len(recent)) :], total

    def near(self, mtype: str, t_s: float, window_s: float) -> list:
        """The recent messages of ``mtype`` (one of :data:`KEEP_RECENT`) stamped within ``window_s``
        of vehicle time ``t_s``: what the autopilot saw at the moment another message was taken,
        however the link delayed or reordered the two."""
        fld = _USEC_FIELDS[mtype]
        lo, hi = (t_s - window_s) * 1e6, (t_s + window_s) * 1e6
        return [m for m in self._recent[mtype] if lo <= (_stamp_usec(m, fld) or -1) <= hi]

    def wait_readable(self, timeout_s: float, extra_fds: tuple[int, ...] = ()) -> None:
        """Sleep until the autopilot's link (or one of ``extra_fds``) has bytes to read, at most
        ``timeout_s``: a control loop that waits on its sockets instead of spinning costs the
        companion's CPU only when something arrives."""
        fd = getattr(self.conn, "fd", None)
        if not isinstance(fd, int) or fd < 0:
            time.sleep(timeout_s)
            return
        try:
            select.select([fd, *extra_fds], [], [], timeout_s)
        except (OSError, ValueError):  # a descriptor closed under us: the next poll reports it
            time.sleep(timeout_s)

    def poll(self) -> int:
        """Handle every waiting message, send what is due; return the number of messages read."""
        n = self._read_filtered() if self.filter is not None else self._read_all()
        self._send_due()
        return n

    def _read_all(self) -> int:
        n = 0
        while True:
            looked = self.monotonic()
            msg = self.conn.recv_match(blocking=False)
            if msg is None:
                self._looked_at = looked
                return n
            n += 1
            self._handle(msg)

    def _read_filtered(self) -> int:
        """Read raw bytes, drop unwanted frames, decode the rest: what ``recv_match`` does, less
        its per-message bookkeeping (``conn.messages``, packet-loss counts) that nothing here reads.
        The tlog, when one is set up, gets the decoded messages as pymavlink would write them."""
        conn, n = self.conn, 0
        while True:
            looked = self.monotonic()
            data = conn.recv(RECV_BYTES)
            if data:
                if conn.logfile_raw:
                    conn.logfile_raw.write(data)
                if conn.first_byte:
                    conn.auto_mavlink_version(data)
                data = self.filter.feed(data)
            # whole frames only reach the parser, but an empty read still drains its buffer
            msgs = conn.mav.parse_buffer(data or b"") or ()
            for msg in msgs:
                if conn.logfile and msg.get_type() != "BAD_DATA":
                    usec = int(time.time() * 1.0e6) & ~3
                    conn.logfile.write(struct.pack(">Q", usec) + msg.get_msgbuf())
                n += 1
                self._handle(msg)
            if not data and not msgs:
                self._looked_at = looked
                return n

    def _from_autopilot(self, msg) -> bool:
        if self.info is None:
            return False
        return msg.get_srcSystem() == self.info.system and msg.get_srcComponent() == self.info.component

    def _handle(self, msg) -> None:
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            return
        now = self.monotonic()
        if (
            mtype == "HEARTBEAT"
            and self.info is None
            and msg.type not in (mavlink.MAV_TYPE_GCS, mavlink.MAV_TYPE_ONBOARD_CONTROLLER)
            and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID
        ):
            self.info = AutopilotInfo(msg.get_srcSystem(), msg.get_srcComponent(), msg.type, msg.autopilot)
            self.conn.mav.srcSystem = msg.get_srcSystem()
            self.conn.target_system = msg.get_srcSystem()
            self.conn.target_component = msg.get_srcComponent()
            self.request_message(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        if not self._from_autopilot(msg):
            return
        fld = _USEC_FIELDS.get(mtype)
        stamp = _stamp_usec(msg, fld) if fld is not None else None
        if stamp is not None and self.clock.known:
            self._watch_reboot(stamp)
        if stamp is None or stamp >= self._stamps.get(mtype, -1):
            # a reordered, older message never replaces a newer one: a link that reorders would
            # hand the take-off an older range reading, or undo a newer script state, for a step
            self.last[mtype] = msg
            if stamp is not None:
                self._stamps[mtype] = stamp
        self._last_rx = now
        self.received[mtype] = self.received.get(mtype, 0) + 1
        recent = self._recent.get(mtype)
        if recent is not None:
            recent.append(msg)
        self._rates.setdefault(mtype, _Rate()).add(now)
        for fn in self._listeners:
            fn(msg)
        if stamp is not None:
            before = self.clock.usec if self.clock.known else None
            self.clock.observe_usec(stamp)
            if before is not None and self.clock.usec - before > GAP_S * 1e6:
                self.resumed_at = self.clock.now()
            if self._last_heartbeat_rx is not None and self._last_heartbeat_vt is None:
                # a HEARTBEAT came before any vehicle time: count the missed ones from the first
                self._last_heartbeat_vt = self.clock.now()
        stream = self.streams.get(mtype)
        if stream is not None:
            t = stamp / 1e6 if stamp is not None else self.clock.now()
            if not stream.stamps or t > stream.stamps[-1]:  # a duplicate or late frame is not a sample
                stream.stamps.append(t)
        if mtype == "HEARTBEAT":
            self._last_heartbeat_rx = now
            self._last_heartbeat_vt = self.clock.now() if self.clock.known else None
        elif mtype == "COMMAND_ACK":
            self._ack(msg, now)
        elif mtype == "STATUSTEXT":
            self.statustext.append(msg.text)
        elif mtype == "AUTOPILOT_VERSION" and self.info is not None:
            v = msg.flight_sw_version
            self.info.firmware = f"{(v >> 24) & 0xFF}.{(v >> 16) & 0xFF}.{(v >> 8) & 0xFF}"
        elif mtype == "NAMED_VALUE_FLOAT":
            name = msg.name.rstrip("\x00") if isinstance(msg.name, str) else msg.name
            if name == "SL_STATE":
                self._script_seen_at = self.clock.now()
                if stamp is None or stamp >= self._script_stamp:  # a late, older state is history
                    self._script_stamp = stamp if stamp is not None else self._script_stamp
                    self.script_state = int(msg.value)
            elif name == "SL_VER" and self.info is not None:
                self.info.script_version = float(msg.value)
                self._script_seen_at = self.clock.now()

    # ------------------------------------------------------------------ sending
    def _send_due(self) -> None:
        now = self.monotonic()
        if now - self._last_heartbeat_tx >= HEARTBEAT_PERIOD_S:
            self._last_heartbeat_tx = now
            self.conn.mav.heartbeat_send(
                mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                mavlink.MAV_AUTOPILOT_INVALID,
                0,
                0,
                mavlink.MAV_STATE_ACTIVE,
            )
        self._timesync(now)
        for h in self._commands:
            if h.done or h.tries == 0 or now - h.sent_at < h.timeout_s:
                continue
            if h.tries > h.retries:
                h.state = "timeout"
            else:
                self._transmit(h)
        self._settle_commands()

    def _echo(self) -> None:
        # tc1 != 0 makes this an answer, not a request (tc1 == 0 asks the autopilot for its time):
        # a lock-stepped simulator reads ts1 as the newest vehicle time seen
        self._last_timesync_usec = self.clock.usec
        self.timesync_sent += 1
        self.conn.mav.timesync_send(max(1, int(self.monotonic() * 1e9)), self.clock.usec * 1000)

    def _timesync(self, now: float) -> None:
        """The lock-step echo, to a vehicle that waits for it and to no other.

        Why it exists: the project's simulated vehicle (``sitl.vehicle --lockstep``) runs at most
        50 ms of its time ahead of the newest time the companion echoed, so a flight does not
        depend on how fast the machine runs the companion. ArduPilot has no use for it: it drops a
        TIMESYNC answer whose ts1 is not its own request (GCS_MAVLINK::handle_timesync), so 50 Hz
        of them only cost a real vehicle's serial link. Which one is at the other end is found by
        asking: one echo of the newest vehicle time (the probe); a lock-stepped vehicle runs to
        its lead past it, says the time it waits at (SYSTEM_TIME) and falls silent; any other runs
        on. A link that stalls just after the probe looks the same: the echoes it then starts are
        dropped by ArduPilot and ignored by a free-running simulator."""
        if not self.clock.known or self.lockstep is False:
            return
        if self.lockstep:
            if self.clock.usec - self._last_timesync_usec >= TIMESYNC_PERIOD_S * 1e6:
                self._echo()
            return
        if self._probe is not None:
            at_us, at_local = self._probe
            ran = self.clock.usec - at_us
            if ran > PROBE_FREE_S * 1e6:
                self.lockstep = False
                return
            silent = self._last_rx is None or self._silence() >= PROBE_STALL_S
            if ran > 0 and silent:
                self.lockstep = True
                self._echo()
                return
            if now - at_local < PROBE_AGAIN_S:
                return
        self._probe = (self.clock.usec, now)
        self._echo()

    def _settle_commands(self) -> None:
        """Forget answered commands; send the next of each id queued behind one that was answered."""
        self._commands = [h for h in self._commands if not h.done]
        busy = {h.command for h in self._commands if h.request is None and h.tries > 0}
        for h in self._commands:
            if h.request is None and h.tries == 0 and h.command not in busy:
                busy.add(h.command)
                self._transmit(h)

    def _ack(self, msg, now: float) -> None:
        """Mark the one request this COMMAND_ACK answers: by its request number when the ACK
        carries one we sent (result_param2), else the one request of that id in flight."""
        sent = [h for h in self._commands if h.command == msg.command and not h.done and h.tries > 0]
        param2 = getattr(msg, "result_param2", 0)  # a MAVLink 1 ACK has no extension fields
        h = next((h for h in sent if h.request is not None and h.request == param2), None)
        if h is None:
            h = next((h for h in sent if h.request is None), None)
        if h is None:
            return  # a late answer to a request that already timed out or was answered
        h.result = msg.result
        if msg.result == mavlink.MAV_RESULT_IN_PROGRESS:
            h.sent_at = now  # being worked on: not lost, do not re-send yet
            return
        h.state = "accepted" if msg.result == mavlink.MAV_RESULT_ACCEPTED else "rejected"
        if h.ok and h.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            cls = mavlink.mavlink_map.get(int(h.params[0]))
            stream = self.streams.get(cls.msgname) if cls is not None else None
            if stream is not None:  # the new rate holds from now: measure it from here
                stream.since = max(stream.since, self.clock.now())
        self._settle_commands()

    def _watch_reboot(self, stamp_us: int) -> None:
        """The autopilot rebooted when its messages keep coming stamped far before the newest
        vehicle time: its clock started again from zero (one late frame is not a reboot)."""
        if stamp_us < self.clock.usec - REBOOT_BACK_S * 1e6:
            self._behind += 1
            if self._behind >= REBOOT_RUN and not self.rebooted:
                self.rebooted = True
                self.reboot_note = (
                    f"autopilot rebooted: its clock went back from {self.clock.now():.1f} s "
                    f"to {stamp_us / 1e6:.1f} s"
                )
        else:
            self._behind = 0

    def _transmit(self, h: CommandHandle) -> None:
        if self.info is None:
            return
        p = list(h.params) + [0.0] * (7 - len(h.params))
        self.conn.mav.command_long_send(
            self.info.system, self.info.component, h.command, min(h.tries, 255), *p
        )
        h.tries += 1
        h.sent_at = self.monotonic()

    def command(
        self,
        command: int,
        *params: float,
        retries: int = 2,
        timeout_s: float = 0.5,
        request: int | None = None,
    ) -> CommandHandle:
        """Send COMMAND_LONG; re-sent up to ``retries`` times ``timeout_s`` apart until answered.

        No command replaces another: each is tracked until its own answer or its last try. With
        ``request`` (a number the autopilot echoes in COMMAND_ACK.result_param2; the caller puts
        it in the parameter the receiver reads it from) it is sent at once and only an ACK
        carrying that number answers it. Without one, an ACK says only which command id it
        answers, so a command whose id already has one in flight waits its turn."""
        if self.info is None:
            raise LinkError("no autopilot found yet: wait_autopilot() before sending commands")
        if len(params) > 7:
            raise LinkError(f"COMMAND_LONG takes at most 7 parameters, got {len(params)}")
        if request is not None and (isinstance(request, bool) or not isinstance(request, int)):
            raise LinkError(f"a request number must be a whole number, got {request!r}")
        if request is not None and not (-(2**31) <= request < 2**31):
            raise LinkError(f"a request number must fit COMMAND_ACK.result_param2 (int32), got {request}")
        h = CommandHandle(command, tuple(float(x) for x in params), retries, timeout_s, request)
        busy = any(c.command == command and c.request is None and not c.done for c in self._commands)
        self._commands.append(h)
        if request is not None or not busy:
            self._transmit(h)
        return h

    def request_message(self, msg_id: int) -> None:
        """Ask once for one message (MAV_CMD_REQUEST_MESSAGE), fire and forget."""
        if self.info is not None:
            self.conn.mav.command_long_send(
                self.info.system,
                self.info.component,
                mavlink.MAV_CMD_REQUEST_MESSAGE,
                0,
                msg_id,
                0,
                0,
                0,
                0,
                0,
                0,
            )

    def request_stream(self, msg_id: int, hz: float) -> CommandHandle:
        """Ask for ``msg_id`` at ``hz`` (MAV_CMD_SET_MESSAGE_INTERVAL; 0 < hz <= 200)."""
        if not (0 < hz <= 200):
            raise LinkError(f"stream rate must be in (0, 200] Hz, got {hz!r}")
        name = mavlink.mavlink_map[msg_id].msgname if msg_id in mavlink.mavlink_map else None
        if name is not None and (self.filter is None or msg_id in self.filter.keep):
            # a stream the link does not decode is not read, so its rate is not checked
            self.streams[name] = _Stream(name, float(hz), self.clock.now())
        return self.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)

    def send_statustext(self, text: str, severity: int = mavlink.MAV_SEVERITY_INFO) -> None:
        """Tell the pilot's ground station (50 characters at most are sent)."""
        self.conn.mav.statustext_send(severity, text.encode("ascii", "replace")[:50])

    # ------------------------------------------------------------------- status
    def rate_hz(self, mtype: str, window: float = 2.0) -> float:
        """Measured arrival rate of one message type over the last ``window`` local seconds."""
        r = self._rates.get(mtype)
        return 0.0 if r is None else r.hz(self.monotonic(), window)

    def delivered_hz(self, name: str) -> float | None:
        """The rate a requested stream delivers (distinct samples per vehicle second) over the last
        :data:`STREAM_WINDOW_S` since it was requested and since telemetry last resumed; None when
        less than :data:`STREAM_MIN_SPAN_S` of vehicle time has passed."""
        s = self.streams[name]
        now = self.clock.now()
        start = max(s.since, self.resumed_at, now - STREAM_WINDOW_S)
        span = now - start
        if span < STREAM_MIN_SPAN_S:
            return None
        return sum(1 for t in s.stamps if start < t <= now) / span

    @property
    def lost_why(self) -> str | None:
        """Which rule of :attr:`lost` holds, in words (None: the link is not lost)."""
        if self.rebooted:
            return "the autopilot rebooted"
        if self._last_heartbeat_rx is None or self._last_rx is None:
            return "no HEARTBEAT yet"
        silent = self._silence()
        if silent > self.link_loss_s:
            return f"nothing heard for {silent:.2f} s of local time"
        hb = self._last_heartbeat_vt
        if hb is not None and self.age(hb) > self.heartbeats_missed * AUTOPILOT_HEARTBEAT_S:
            return f"no HEARTBEAT for {self.age(hb):.2f} s of vehicle time"
        return None

    def _silence(self) -> float:
        """Local seconds the autopilot has been silent for, as far as the reads show: from its
        newest message to the newest read that found nothing more (time since that read is not
        counted: nobody looked)."""
        if self._last_rx is None:
            return math.inf
        looked = self._looked_at if self._looked_at is not None else self._last_rx
        return max(0.0, looked - self._last_rx)

    @property
    def lost(self) -> bool:
        """The autopilot silent for ``link_loss_s`` local seconds, talking but with
        ``heartbeats_missed`` of its 1 Hz HEARTBEATs missed in its own time, or rebooted (true
        before the first HEARTBEAT).

        Silence is measured locally, since a silent vehicle's clock stands still, and only up to
        the newest read that found the link drained (a companion's own pause is not the
        autopilot's silence); missing
        HEARTBEATs are counted in vehicle time, so a simulated vehicle slowed by a loaded machine
        (its 1 Hz heartbeat further apart in local time) is not taken for a lost one. One lost
        HEARTBEAT (a dropped frame on a noisy link) is not link loss."""
        return self.lost_why is not None

    def age(self, stamp_s: float) -> float:
        """Vehicle seconds since ``stamp_s``, counted from where telemetry resumed if it had a gap
        since: what the link missed during a gap says nothing about the vehicle or its sensors."""
        return self.clock.now() - max(stamp_s, self.resumed_at)

    @property
    def script_present(self) -> bool:
        """The on-board script announced itself within the last second of the autopilot's time: a
        simulation stalled by a loaded machine is not a silent script (a silent autopilot is link
        loss, on the companion's own clock)."""
        return self._script_seen_at is not None and self.age(self._script_seen_at) <= SCRIPT_SILENT_S

    def wait_autopilot(
        self, timeout_s: float = 10.0, sleep: Callable[[float], None] = time.sleep
    ) -> AutopilotInfo:
        """Poll until an autopilot heartbeat (and, briefly, its version and the on-board script's
        once-a-second SL_VER) arrives; raise if none."""
        t0 = self.monotonic()

        def waiting() -> bool:
            if self.info is None:
                return True
            age = self.monotonic() - t0
            return (self.info.firmware == "unknown" and age < 1.0) or (
                self.info.script_version is None and age < SCRIPT_ANNOUNCE_WAIT_S
            )

        while waiting():
            self.poll()
            if self.info is None and self.monotonic() - t0 > timeout_s:
                raise LinkError(f"no autopilot heartbeat within {timeout_s:g} s")
            sleep(0.01)
        return self.info

    def settle(self, timeout_s: float = 1.5, sleep: Callable[[float], None] = time.sleep) -> int:
        """Poll until every command sent is answered or out of tries, at most ``timeout_s`` local
        seconds; returns how many were still unanswered. Before closing: ArduPilot SITL drops what
        it had not yet read from a client that disconnects, and a real serial link may be cut, so
        a disarm or an end of the reverse thrust sent last is seen answered (or re-sent) first."""
        end = self.monotonic() + timeout_s
        while self._commands and self.monotonic() < end:
            self.poll()
            self._commands = [h for h in self._commands if not h.done]
            sleep(0.005)
        return len(self._commands)

    def close(self) -> None:
        """Close the connection."""
        self.conn.close()


def stream_refusal(link: Link | None, min_fraction: float) -> str | None:
    """Why the requested streams cannot carry a landing, or None: the first stream delivering less
    than ``min_fraction`` of its requested rate in vehicle time (a refused request delivers
    nothing), or one not measured yet. None without a link (a machine stepped without one)."""
    if link is None or not isinstance(link, Link):
        return None
    for name, s in link.streams.items():
        got = link.delivered_hz(name)
        if got is None:
            return f"stream {name} not measured yet ({STREAM_MIN_SPAN_S:g} s of vehicle time needed)"
        if got < min_fraction * s.hz:
            return (
                f"stream {name} delivers {got:.1f} Hz of {s.hz:g} Hz requested (less than {min_fraction:.0%})"
            )
    return None
