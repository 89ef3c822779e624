"""The companion's MAVLink link to the autopilot: non-blocking, polled by the state machine.

One :class:`Link` owns the connection. :meth:`Link.poll` drains every waiting message without
blocking (:mod:`.transport`), keeps the vehicle clock and the newest message of each type, sends the
companion's heartbeat (1 Hz) and, where a simulator asked for it, the lock-step echo
(:mod:`.lockstep`); it re-sends commands that were not acknowledged and expires the ones that ran
out of tries (:mod:`.commands`). It measures each requested stream's delivered rate in vehicle time
and notices an autopilot that rebooted under it (:mod:`.health`).

The newest messages (:attr:`Link.last`) are the link's own store, not pymavlink's
``conn.messages``: pymavlink replaces an entry with whatever arrived last, and a link that reorders
frames (a radio, a relay) would then hand the landing an older range reading or undo a newer
script state for a step; here a message stamped older than the one held never replaces it. The
listeners are the link's own for the same reason as the filtered reader: pymavlink calls its
``message_hooks`` only from ``recv_msg``, which the filtered reader does not run.
"""

from __future__ import annotations

import contextlib
import math
import select
import time
from collections import deque
from collections.abc import Callable, Iterable

from pymavlink import mavutil

from slopelander.controller.clock import VehicleClock
from slopelander.controller.link.commands import CommandHandle, Commands
from slopelander.controller.link.frames import FrameFilter
from slopelander.controller.link.health import (
    STREAM_MIN_SPAN_S,
    STREAM_WINDOW_S,
    Rate,
    RebootWatch,
    Stream,
    stream_refusal,
)
from slopelander.controller.link.lockstep import LockstepEcho
from slopelander.controller.link.messages import (
    KEEP_RECENT,
    LANDING_MESSAGES,
    RECENT_LEN,
    USEC_FIELDS,
    AutopilotInfo,
    LinkError,
    message_ids,
    stamp_usec,
)
from slopelander.controller.link.messages import mavlink as mavlink
from slopelander.controller.link.transport import read_all, read_filtered

__all__ = [
    "LANDING_MESSAGES",
    "STREAM_MIN_SPAN_S",
    "STREAM_WINDOW_S",
    "AutopilotInfo",
    "CommandHandle",
    "Link",
    "LinkError",
    "mavlink",
    "message_ids",
    "stream_refusal",
]

COMPANION_COMPONENT = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER
HEARTBEAT_PERIOD_S = 1.0
#: ArduPilot sends its HEARTBEAT at 1 Hz on every MAVLink channel (GCS_MAVLINK::update_send)
AUTOPILOT_HEARTBEAT_S = 1.0
SCRIPT_SILENT_S = 1.0  # vehicle seconds without SL_STATE: the script is silent
SCRIPT_ANNOUNCE_WAIT_S = 1.5  # local s: the script's SL_VER comes once a second
#: a jump in the newest vehicle time larger than this (s) is a telemetry gap (a 200 Hz IMU stream
#: normally advances it by 5 ms): ages of what the link holds are counted from where it resumed
GAP_S = 0.1


class Link:
    """A polled MAVLink connection to one autopilot.

    ``url`` is any pymavlink connection string (``udpin:0.0.0.0:14550``, ``tcp:host:5760``,
    ``/dev/ttyACM0,921600``). :attr:`lost` becomes true after ``link_loss_s`` with nothing from the
    autopilot (local time), with its messages but ``heartbeats_missed`` of its 1 Hz HEARTBEATs
    missed (vehicle time), or once it rebooted.
    ``decode``: the message names to decode (e.g. :data:`LANDING_MESSAGES`); frames of any other
    message are dropped unread (see :mod:`.frames`). None decodes everything through pymavlink's
    own reader. ``lockstep``: echo the vehicle's time to a simulator that waits for it
    (:mod:`.lockstep`); never for a real autopilot.
    """

    def __init__(
        self,
        url: str,
        *,
        link_loss_s: float = 1.5,
        heartbeats_missed: int = 3,
        monotonic: Callable[[], float] = time.monotonic,
        decode: Iterable[str] | None = None,
        lockstep: bool = False,
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
        self._rates: dict[str, Rate] = {}
        self.commands = Commands(self._transmit, monotonic)
        self._last_heartbeat_rx: float | None = None
        self._last_heartbeat_vt: float | None = None  # vehicle time of the newest HEARTBEAT
        self._last_rx: float | None = None  # local time of the newest message from the autopilot
        #: local time of the newest read that found the link drained: silence is judged up to it,
        #: so a companion that stalls (a long garbage collection, a starved process) between two
        #: reads does not take its own pause for the autopilot's silence
        self._looked_at: float | None = None
        self._last_heartbeat_tx = -math.inf
        #: the lock-step echo, when a simulator asked for it
        self.lockstep = LockstepEcho(self.conn, self.clock, monotonic) if lockstep else None
        self.reboot = RebootWatch()
        #: requested streams by message name (see :meth:`delivered_hz`)
        self.streams: dict[str, Stream] = {}
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

    def remove_listener(self, fn: Callable[[object], None]) -> None:
        """Stop calling ``fn`` (one added by :meth:`add_listener`; absent: nothing to do)."""
        with contextlib.suppress(ValueError):
            self._listeners.remove(fn)

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
        fld = USEC_FIELDS[mtype]
        lo, hi = (t_s - window_s) * 1e6, (t_s + window_s) * 1e6
        return [m for m in self._recent[mtype] if lo <= (stamp_usec(m, fld) or -1) <= hi]

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
        if self.filter is not None:
            n, self._looked_at = read_filtered(self.conn, self.filter, self._handle, self.monotonic)
        else:
            n, self._looked_at = read_all(self.conn, self._handle, self.monotonic)
        self._send_due()
        return n

    def _from_autopilot(self, msg) -> bool:
        if self.info is None:
            return False
        return msg.get_srcSystem() == self.info.system and msg.get_srcComponent() == self.info.component

    def _handle(self, msg) -> None:
        """One message in: the autopilot found (first HEARTBEAT), then, for the autopilot's own
        messages, the newest kept, the clock moved on, the listeners told, and the message's
        own meaning read (:data:`_BY_TYPE`)."""
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            return
        now = self.monotonic()
        if mtype == "HEARTBEAT" and self.info is None:
            self._found(msg)
        if not self._from_autopilot(msg):
            return
        fld = USEC_FIELDS.get(mtype)
        stamp = stamp_usec(msg, fld) if fld is not None else None
        self._keep(mtype, msg, stamp, now)
        for fn in self._listeners:
            fn(msg)
        if stamp is not None:
            self._observe_clock(stamp)
        stream = self.streams.get(mtype)
        if stream is not None:
            stream.add(stamp / 1e6 if stamp is not None else self.clock.now())
        read = _BY_TYPE.get(mtype)
        if read is not None:
            read(self, msg, stamp, now)

    def _found(self, msg) -> None:
        """The first HEARTBEAT of an autopilot (not a ground station, not another companion)."""
        if msg.type in (mavlink.MAV_TYPE_GCS, mavlink.MAV_TYPE_ONBOARD_CONTROLLER):
            return
        if msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
            return
        self.info = AutopilotInfo(msg.get_srcSystem(), msg.get_srcComponent(), msg.type, msg.autopilot)
        self.conn.mav.srcSystem = msg.get_srcSystem()
        self.conn.target_system = msg.get_srcSystem()
        self.conn.target_component = msg.get_srcComponent()
        self.request_message(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)

    def _keep(self, mtype: str, msg, stamp: int | None, now: float) -> None:
        """The newest of its type (a reordered, older message never replaces a newer one: a link
        that reorders would hand the take-off an older range reading, or undo a newer script
        state, for a step), the recent ones a reader needs every one of, counts and rates."""
        if stamp is not None and self.clock.known:
            self.reboot.observe(stamp, self.clock.usec)
        if stamp is None or stamp >= self._stamps.get(mtype, -1):
            self.last[mtype] = msg
            if stamp is not None:
                self._stamps[mtype] = stamp
        self._last_rx = now
        self.received[mtype] = self.received.get(mtype, 0) + 1
        recent = self._recent.get(mtype)
        if recent is not None:
            recent.append(msg)
        self._rates.setdefault(mtype, Rate()).add(now)

    def _observe_clock(self, stamp: int) -> None:
        """The vehicle's clock moved to ``stamp`` (us); a jump past GAP_S is a telemetry gap."""
        before = self.clock.usec if self.clock.known else None
        self.clock.observe_usec(stamp)
        if before is not None and self.clock.usec - before > GAP_S * 1e6:
            self.resumed_at = self.clock.now()
        if self._last_heartbeat_rx is not None and self._last_heartbeat_vt is None:
            # a HEARTBEAT came before any vehicle time: count the missed ones from the first
            self._last_heartbeat_vt = self.clock.now()

    def _read_heartbeat(self, msg, stamp: int | None, now: float) -> None:
        self._last_heartbeat_rx = now
        self._last_heartbeat_vt = self.clock.now() if self.clock.known else None

    def _read_ack(self, msg, stamp: int | None, now: float) -> None:
        h = self.commands.ack(msg, now)
        if h is not None and h.ok and h.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            cls = mavlink.mavlink_map.get(int(h.params[0]))
            stream = self.streams.get(cls.msgname) if cls is not None else None
            if stream is not None:  # the new rate holds from now: measure it from here
                stream.since = max(stream.since, self.clock.now())

    def _read_statustext(self, msg, stamp: int | None, now: float) -> None:
        self.statustext.append(msg.text)

    def _read_version(self, msg, stamp: int | None, now: float) -> None:
        if self.info is not None:
            v = msg.flight_sw_version
            self.info.firmware = f"{(v >> 24) & 0xFF}.{(v >> 16) & 0xFF}.{(v >> 8) & 0xFF}"

    def _read_named_value(self, msg, stamp: int | None, now: float) -> None:
        """The on-board script's state (SL_STATE, 5 Hz) and version (SL_VER, 1 Hz)."""
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
        if self.lockstep is not None:
            self.lockstep.due()
        self.commands.resend_due(now)

    def _transmit(self, h: CommandHandle) -> None:
        if self.info is None:
            return
        p = list(h.params) + [0.0] * (7 - len(h.params))
        self.conn.mav.command_long_send(
            self.info.system, self.info.component, h.command, min(h.tries, 255), *p
        )

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
        return self.commands.send(command, params, retries=retries, timeout_s=timeout_s, request=request)

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
            self.streams[name] = Stream(name, float(hz), self.clock.now())
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
        return self.streams[name].delivered_hz(self.clock.now(), self.resumed_at)

    @property
    def lost_why(self) -> str | None:
        """Which rule of :attr:`lost` holds, in words (None: the link is not lost)."""
        if self.reboot.rebooted:
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
        counted: nobody looked). In lock-step, a simulator the echo holds for the leg board is
        not silent (:mod:`.lockstep`)."""
        if self._last_rx is None:
            return math.inf
        looked = self._looked_at if self._looked_at is not None else self._last_rx
        if self.lockstep is not None:  # a simulator held for the leg board is our own silence
            if self.lockstep.holding:
                return 0.0
            return max(0.0, looked - max(self._last_rx, self.lockstep.released_at))
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
        while self.commands.pending and self.monotonic() < end:
            self.poll()
            self.commands.settle()
            sleep(0.005)
        return len(self.commands.pending)

    def close(self) -> None:
        """Close the connection."""
        self.conn.close()

    @property
    def rebooted(self) -> bool:
        """The autopilot rebooted under the link (its clock went back): lost for this landing."""
        return self.reboot.rebooted

    @property
    def reboot_note(self) -> str | None:
        """What the reboot looked like, for the pilot."""
        return self.reboot.note


#: what each message means to the link beyond being kept (:meth:`Link._handle`)
_BY_TYPE: dict[str, Callable] = {
    "HEARTBEAT": Link._read_heartbeat,
    "COMMAND_ACK": Link._read_ack,
    "STATUSTEXT": Link._read_statustext,
    "AUTOPILOT_VERSION": Link._read_version,
    "NAMED_VALUE_FLOAT": Link._read_named_value,
}
