"""The UDP side: one reply per ArduPilot frame, in lock-step.

ArduPilot sends a servo packet, then waits for the reply before its next frame; if none comes
it re-sends the same packet about once a second. So the server steps the physics once per new
frame count and answers a repeated frame count with the reply it already sent (the physics is
not stepped twice). A frame count going backwards, or packets from a new address, is a
restarted ArduPilot: the physics resets, and its timestamp going backwards tells ArduPilot so.
A datagram that is not a servo packet gets no reply and one line on stderr. With a
:class:`~slopelander_sitl.json_physics.companion_gate.CompanionGate` a new frame is stepped only once the
companion is close enough behind (its module says why).
"""

from __future__ import annotations

import socket
import sys
import time
from dataclasses import dataclass

from slopelander.errors import SlopelanderError
from slopelander_sitl.json_physics.companion_gate import CompanionGate
from slopelander_sitl.json_physics.physics import JsonPhysics
from slopelander_sitl.json_physics.pilot_rc import PilotRc
from slopelander_sitl.json_physics.protocol import ProtocolError, decode_servo_packet, encode_reply


class ServerError(SlopelanderError):
    """The server cannot listen where it was asked to."""


@dataclass
class Counters:
    frames: int = 0  # physics frames stepped
    repeats: int = 0  # re-sent frames answered again without stepping
    missed: int = 0  # frame counts skipped by ArduPilot
    resets: int = 0  # ArduPilot restarts (and physics failures) that reset the physics
    rejected: int = 0  # datagrams that were not servo packets


class JsonServer:
    def __init__(
        self,
        physics: JsonPhysics,
        port: int,
        host: str = "127.0.0.1",
        rc: PilotRc | None = None,
        gate: CompanionGate | None = None,
    ) -> None:
        self.physics = physics
        self.gate = gate
        self.rc = rc  # the scenario's pilot on ArduPilot's RC input, sent as the physics time goes
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            raise ServerError(f"cannot listen on udp {host}:{port}: {exc.strerror}") from None
        self.port = self.sock.getsockname()[1]
        self.peer: tuple[str, int] | None = None
        self.last_count: int | None = None
        self.last_reply = b""
        self.count = Counters()
        self.running = True
        self._warned: dict[str, float] = {}

    def stop(self) -> None:
        """From a signal handler: leave the serving loop, and any wait for the companion, soon."""
        self.running = False
        if self.gate is not None:
            self.gate.stopping = True

    def close(self) -> None:
        self.sock.close()

    def serve_forever(self) -> None:
        self.sock.settimeout(0.2)
        while self.running:
            try:
                data, addr = self.sock.recvfrom(2048)
            except TimeoutError:
                continue
            except OSError as exc:  # e.g. ICMP port unreachable from a peer that went away
                self._warn("socket", f"receive failed: {exc}")
                continue
            reply = self.handle(data, addr)
            if reply is not None:
                try:
                    self.sock.sendto(reply, addr)
                except OSError as exc:
                    self._warn("send", f"cannot reply to {addr[0]}:{addr[1]}: {exc}")

    def handle(self, data: bytes, addr: tuple[str, int]) -> bytes | None:
        """The reply to one datagram, or None when it gets none."""
        try:
            frame = decode_servo_packet(data)
        except ProtocolError as exc:
            self.count.rejected += 1
            self._warn("packet", f"ignored a datagram from {addr[0]}:{addr[1]}: {exc}")
            return None
        if addr != self.peer:
            if self.peer is not None:
                self._reset(f"ArduPilot now at {addr[0]}:{addr[1]} (was {self.peer[0]}:{self.peer[1]})")
            else:
                self._note(f"ArduPilot connected from {addr[0]}:{addr[1]} at {frame.frame_rate} Hz")
            self.peer = addr
        elif frame.frame_count == self.last_count:
            self.count.repeats += 1
            return self.last_reply
        elif self.last_count is not None and frame.frame_count < self.last_count:
            self._reset(
                f"frame count went back from {self.last_count} to {frame.frame_count}: ArduPilot restarted"
            )
        elif self.last_count is not None and frame.frame_count > self.last_count + 1:
            self.count.missed += frame.frame_count - self.last_count - 1
        self.last_count = frame.frame_count
        if self.gate is not None:
            self.gate.wait(self.physics.t)
            self.gate.pace(self.physics.t, self.physics.height_m(), self.physics.script_may_time())
        try:
            self.physics.step(frame.dt, frame.pwm[:4])
            reply = self.physics.reply()  # encode_reply(fdm()), formatted without the Fdm
        except (ProtocolError, SlopelanderError, ValueError, FloatingPointError) as exc:
            self._reset(f"physics failed ({exc})")
            reply = encode_reply(self.physics.fdm())
        self.count.frames += 1
        self.last_reply = reply
        if self.rc is not None:
            self.rc.update(self.physics.t)
        return reply

    def _reset(self, why: str) -> None:
        self.count.resets += 1
        self._note(f"{why}: physics reset")
        self.physics.reset()
        if self.gate is not None:
            self.gate.reset()

    def _note(self, text: str) -> None:
        print(f"json_physics: {text}", file=sys.stderr, flush=True)

    def _warn(self, kind: str, text: str) -> None:
        """At most one line per second per kind: a flood of bad packets must not flood stderr."""
        now = time.monotonic()
        if now - self._warned.get(kind, -1e9) >= 1.0:
            self._warned[kind] = now
            self._note(text)
