"""The companion's MAVLink link to the autopilot: non-blocking, polled by the state machine.

One :class:`Link` owns the connection. :meth:`Link.poll` drains every waiting message without
blocking, keeps the vehicle clock, sends the companion's heartbeat (1 Hz) and the TIMESYNC echo
(about 50 Hz of vehicle time; a lock-stepped simulator waits on it), re-sends commands that were
not acknowledged and expires the ones that ran out of tries. Commands return a
:class:`CommandHandle` that the caller polls instead of waiting.
"""

from __future__ import annotations

import math
import select
import struct
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from pymavlink import mavutil

from slopelander.controller.clock import VehicleClock
from slopelander.controller.frames import FrameFilter
from slopelander.errors import SlopelanderError

mavlink = mavutil.mavlink

COMPANION_COMPONENT = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER
HEARTBEAT_PERIOD_S = 1.0
TIMESYNC_PERIOD_S = 0.02
SCRIPT_SILENT_S = 1.0  # vehicle seconds without SL_STATE: the script is silent
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
    """One COMMAND_LONG in flight: poll ``state`` ('pending', 'accepted', 'rejected', 'timeout')."""

    command: int
    params: tuple[float, ...]
    retries: int
    timeout_s: float
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
        script = "absent" if self.script_version is None else f"v{self.script_version:g}"
        return (
            f"system {self.system} component {self.component}: "
            f"{vt.name if vt else self.vehicle_type}, {ap.name if ap else self.autopilot}, "
            f"firmware {self.firmware}, on-board script {script}"
        )


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
    autopilot (local time), or with its messages but no HEARTBEAT for ``link_loss_s`` of vehicle time.
    ``decode``: the message names to decode (e.g. :data:`LANDING_MESSAGES`); frames of any other
    message are dropped unread (see :mod:`slopelander.controller.frames`). None decodes everything
    through pymavlink's own reader.
    """

    def __init__(
        self,
        url: str,
        *,
        link_loss_s: float = 1.5,
        monotonic: Callable[[], float] = time.monotonic,
        decode: Iterable[str] | None = None,
    ) -> None:
        if not isinstance(url, str) or not url.strip():
            raise LinkError("connection string is empty (expected e.g. udpin:0.0.0.0:14550)")
        if not (link_loss_s > 0 and math.isfinite(link_loss_s)):
            raise LinkError(f"link_loss_s must be a positive number of seconds, got {link_loss_s!r}")
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
        self.info: AutopilotInfo | None = None
        self.last: dict[str, object] = {}
        self.statustext: deque[str] = deque(maxlen=50)
        self._rates: dict[str, _Rate] = {}
        self._commands: list[CommandHandle] = []
        self._last_heartbeat_rx: float | None = None
        self._last_heartbeat_vt: float | None = None  # vehicle time of the newest HEARTBEAT
        self._last_rx: float | None = None  # local time of the newest message from the autopilot
        self._last_heartbeat_tx = -math.inf
        self._last_timesync_usec = 0
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
            msg = self.conn.recv_match(blocking=False)
            if msg is None:
                return n
            n += 1
            self._handle(msg)

    def _read_filtered(self) -> int:
        """Read raw bytes, drop unwanted frames, decode the rest: what ``recv_match`` does, less
        its per-message bookkeeping (``conn.messages``, packet-loss counts) that nothing here reads.
        The tlog, when one is set up, gets the decoded messages as pymavlink would write them."""
        conn, n = self.conn, 0
        while True:
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
        if mtype == "HEARTBEAT":
            self._last_heartbeat_rx = now
            self._last_heartbeat_vt = self.clock.now() if self.clock.known else None
        elif mtype == "COMMAND_ACK":
            for h in self._commands:
                if h.command == msg.command and not h.done:
                    h.result = msg.result
                    if msg.result == mavlink.MAV_RESULT_IN_PROGRESS:
                        continue
                    h.state = "accepted" if msg.result == mavlink.MAV_RESULT_ACCEPTED else "rejected"
                    break
            self._commands = [h for h in self._commands if not h.done]
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
        if self.clock.known and self.clock.usec - self._last_timesync_usec >= TIMESYNC_PERIOD_S * 1e6:
            self._last_timesync_usec = self.clock.usec
            # tc1 != 0 makes this an answer, not a request (tc1 == 0 asks the autopilot for its
            # time): a lock-stepped simulator reads ts1 as the newest vehicle time seen, and
            # ArduPilot drops answers whose ts1 is not one of its own requests.
            self.conn.mav.timesync_send(max(1, int(self.monotonic() * 1e9)), self.clock.usec * 1000)
        for h in self._commands:
            if h.done or now - h.sent_at < h.timeout_s:
                continue
            if h.tries > h.retries:
                h.state = "timeout"
            else:
                self._transmit(h)
        self._commands = [h for h in self._commands if not h.done]

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
        self, command: int, *params: float, retries: int = 2, timeout_s: float = 0.5
    ) -> CommandHandle:
        """Send COMMAND_LONG now; re-sent up to ``retries`` times ``timeout_s`` apart until answered."""
        if self.info is None:
            raise LinkError("no autopilot found yet: wait_autopilot() before sending commands")
        if len(params) > 7:
            raise LinkError(f"COMMAND_LONG takes at most 7 parameters, got {len(params)}")
        h = CommandHandle(command, tuple(float(x) for x in params), retries, timeout_s)
        # A newer command of the same id supersedes an older one still pending.
        for old in self._commands:
            if old.command == command and not old.done:
                old.state = "timeout"
        self._commands = [c for c in self._commands if not c.done]
        self._transmit(h)
        self._commands.append(h)
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
        return self.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)

    def send_statustext(self, text: str, severity: int = mavlink.MAV_SEVERITY_INFO) -> None:
        """Tell the pilot's ground station (50 characters at most are sent)."""
        self.conn.mav.statustext_send(severity, text.encode("ascii", "replace")[:50])

    # ------------------------------------------------------------------- status
    def rate_hz(self, mtype: str, window: float = 2.0) -> float:
        """Measured arrival rate of one message type over the last ``window`` local seconds."""
        r = self._rates.get(mtype)
        return 0.0 if r is None else r.hz(self.monotonic(), window)

    @property
    def lost(self) -> bool:
        """The autopilot silent for ``link_loss_s`` local seconds, or talking without a HEARTBEAT
        for ``link_loss_s`` of its own time (true before the first HEARTBEAT).

        Silence is measured locally, since a silent vehicle's clock stands still; a missing
        HEARTBEAT is measured in vehicle time, so a simulated vehicle slowed by a loaded machine
        (its 1 Hz heartbeat further apart in local time) is not taken for a lost one."""
        if self._last_heartbeat_rx is None or self._last_rx is None:
            return True
        if self.monotonic() - self._last_rx > self.link_loss_s:
            return True
        hb = self._last_heartbeat_vt
        return hb is not None and self.age(hb) > self.link_loss_s

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
        """Poll until an autopilot heartbeat (and its version, briefly) arrives; raise if none."""
        t0 = self.monotonic()
        while self.info is None or (self.info.firmware == "unknown" and self.monotonic() - t0 < 1.0):
            self.poll()
            if self.info is None and self.monotonic() - t0 > timeout_s:
                raise LinkError(f"no autopilot heartbeat within {timeout_s:g} s")
            sleep(0.01)
        return self.info

    def close(self) -> None:
        """Close the connection."""
        self.conn.close()
