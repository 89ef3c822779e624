"""Commands to the autopilot (COMMAND_LONG): each tracked until its own answer or its last try.

ArduPilot's COMMAND_ACK names only the command id (``GCS_MAVLINK::handle_command_long_packet``
answers with ``mavlink_msg_command_ack_send(chan, packet.command, result, ...)``), so two requests
of one id in flight cannot be told apart: they are sent one at a time, in order. A command whose
receiver echoes a request number in ``result_param2`` (the on-board script does) is matched by it.

A request given up on (out of tries) may still be answered late, and that ACK would confirm the
next request of its id. So an id whose request timed out is held back for :data:`QUARANTINE_S`:
a new request of it waits its turn (sent once the quarantine ends), and an ACK of the id arriving
meanwhile, with nothing of it in flight, is the late answer and is dropped. A state that must know
(a mode change) reads the HEARTBEAT as well; the ACK is only the quick answer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from slopelander.controller.link.messages import LinkError, mavlink

#: local seconds a command id whose request timed out is held back (its late ACK is dropped)
QUARANTINE_S = 1.0


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

    def describe(self) -> str:
        """The state and the autopilot's result, in words."""
        result = "" if self.result is None else f" (result {self.result})"
        return f"{self.state}{result}"


class Commands:
    """The commands in flight: sent through ``transmit(handle)``, re-sent after their timeout,
    answered by :meth:`ack`. ``monotonic`` is the companion's local clock."""

    def __init__(self, transmit: Callable[[CommandHandle], None], monotonic: Callable[[], float]) -> None:
        self._transmit = transmit
        self.monotonic = monotonic
        #: every command not yet answered nor out of tries, oldest first
        self.pending: list[CommandHandle] = []
        #: command id -> local time until which it is held back after a request of it timed out
        self.quarantine: dict[int, float] = {}

    def send(
        self,
        command: int,
        params: tuple[float, ...],
        *,
        retries: int,
        timeout_s: float,
        request: int | None,
    ) -> CommandHandle:
        """Track a new command; sent at once unless one of its id (and no request number) is in flight."""
        if len(params) > 7:
            raise LinkError(f"COMMAND_LONG takes at most 7 parameters, got {len(params)}")
        if request is not None and (isinstance(request, bool) or not isinstance(request, int)):
            raise LinkError(f"a request number must be a whole number, got {request!r}")
        if request is not None and not (-(2**31) <= request < 2**31):
            raise LinkError(f"a request number must fit COMMAND_ACK.result_param2 (int32), got {request}")
        h = CommandHandle(command, tuple(float(x) for x in params), retries, timeout_s, request)
        busy = any(c.command == command and c.request is None and not c.done for c in self.pending)
        self.pending.append(h)
        if request is not None or not (busy or self._held(command)):
            self._send(h)
        return h

    def _held(self, command: int) -> bool:
        until = self.quarantine.get(command)
        if until is None:
            return False
        if self.monotonic() >= until:
            del self.quarantine[command]
            return False
        return True

    def _send(self, h: CommandHandle) -> None:
        self._transmit(h)
        h.tries += 1
        h.sent_at = self.monotonic()

    def resend_due(self, now: float) -> None:
        """Re-send what waited its timeout; give up on what ran out of tries."""
        for h in self.pending:
            if h.done or h.tries == 0 or now - h.sent_at < h.timeout_s:
                continue
            if h.tries > h.retries:
                h.state = "timeout"
                if h.request is None:  # its late ACK must not answer the next of its id
                    self.quarantine[h.command] = now + QUARANTINE_S
            else:
                self._send(h)
        self.settle()

    def settle(self) -> None:
        """Forget answered commands; send the next of each id queued behind one that was answered."""
        self.pending = [h for h in self.pending if not h.done]
        busy = {h.command for h in self.pending if h.request is None and h.tries > 0}
        for h in self.pending:
            if h.request is None and h.tries == 0 and h.command not in busy and not self._held(h.command):
                busy.add(h.command)
                self._send(h)

    def ack(self, msg, now: float) -> CommandHandle | None:
        """Mark the one request this COMMAND_ACK answers (returned): by its request number when the
        ACK carries one we sent (result_param2), else the one request of that id in flight."""
        sent = [h for h in self.pending if h.command == msg.command and not h.done and h.tries > 0]
        param2 = getattr(msg, "result_param2", 0)  # a MAVLink 1 ACK has no extension fields
        h = next((h for h in sent if h.request is not None and h.request == param2), None)
        if h is None:
            h = next((h for h in sent if h.request is None), None)
        if h is None:
            return None  # a late answer to a request that already timed out or was answered
        h.result = msg.result
        if msg.result == mavlink.MAV_RESULT_IN_PROGRESS:
            h.sent_at = now  # being worked on: not lost, do not re-send yet
            return None
        h.state = "accepted" if msg.result == mavlink.MAV_RESULT_ACCEPTED else "rejected"
        self.settle()
        return h
