"""The simulated board as a process: a pseudo-terminal speaking the leg protocol.

It owns the pty master, advances :class:`LegBoardPhysics` in board time, answers commands
with the shared codec, sends STATUS periodically and serves the control channel (a UNIX
socket, JSON lines) through which tests inject faults and the vehicle simulator feeds joint
angles.

Board time follows one of two clocks. ``wall`` (the default, for a board used on its own):
``speed`` × wall time. ``external`` (a board a simulated vehicle drives): only the times the
vehicle sends (control op ``advance``), so board and vehicle cannot drift apart under machine
load; a board fed no time stands still, sends no STATUS and only answers commands.
"""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import random
import select
import socket
import time
import tty
from dataclasses import dataclass
from pathlib import Path

from sitl.legboard.physics import LegBoardPhysics
from slopelander.legs import codec, messages
from slopelander.legs.framing import MAX_PAYLOAD
from slopelander.legs.messages import Capability, NakCode, legs_in

IO_FAULTS = ("silent", "corrupt", "unplug")
LEG_FAULTS = ("stuck", "slip", "overcurrent")
FAULT_KINDS = LEG_FAULTS + IO_FAULTS
CLOCKS = ("wall", "external")
MAX_ADVANCE_S = 10.0  # board seconds one ``advance`` may step (a guard against a runaway time)


@dataclass(frozen=True)
class FaultSpec:
    """A fault to inject: ``kind``, a leg or a rate as ``arg``, at board time ``at_s``."""

    kind: str
    arg: float | None = None
    at_s: float = 0.0

    @classmethod
    def parse(cls, text: str) -> FaultSpec:
        """``KIND[:ARG][@T]``, e.g. ``stuck:1``, ``corrupt:0.2``, ``unplug@5``."""
        spec, _, at = text.partition("@")
        kind, _, arg = spec.partition(":")
        if kind not in FAULT_KINDS:
            raise ValueError(f"unknown fault {kind!r}; one of {', '.join(FAULT_KINDS)}")
        if kind in LEG_FAULTS and not arg:
            raise ValueError(f"fault {kind} needs a leg: {kind}:LEG")
        return cls(kind, float(arg) if arg else None, float(at) if at else 0.0)


class BoardServer:
    """One simulated board: pty, physics, protocol, control channel."""

    def __init__(
        self,
        physics: LegBoardPhysics | None = None,
        *,
        link: str | Path | None = None,
        control: str | Path | None = None,
        speed: float = 1.0,
        dt: float = 0.004,
        status_period_ms: int = 100,
        min_status_wall_s: float = 0.01,
        angle_stop: bool = True,
        faults: tuple[FaultSpec, ...] = (),
        seed: int = 0,
        clock: str = "wall",
    ) -> None:
        if clock not in CLOCKS:
            raise ValueError(f"unknown clock {clock!r}; one of {', '.join(CLOCKS)}")
        self.clock = clock
        self.clock_s: float | None = None  # the newest time fed to an external clock
        self.physics = physics or LegBoardPhysics(seed=seed)
        self.link = Path(link) if link else None
        self.control_path = Path(control) if control else (Path(f"{self.link}.ctl") if self.link else None)
        self.speed = speed
        self.dt = dt
        self.default_period_s = status_period_ms / 1000.0
        self.min_status_wall_s = min_status_wall_s
        self.capabilities = Capability.SIMULATED | (Capability.ANGLE_STOP if angle_stop else 0)
        self.scheduled = sorted(faults, key=lambda f: f.at_s)
        self.silent = False
        self.corrupt_rate = 0.0
        self.unplugged = False
        self.running = False
        self.slave_path = ""
        self._rng = random.Random(seed + 1)
        self._decoder = codec.Decoder()
        self._seq = 0
        self._hello = False
        self._period_s = self.default_period_s
        self._last_cmd_seq = 0
        self._next_status = 0.0
        self._last_status_wall = 0.0
        self._master = -1
        self._slave = -1
        self._listener: socket.socket | None = None
        self._clients: dict[socket.socket, bytearray] = {}
        self.dropped_bytes = 0

    # ---- life cycle -------------------------------------------------------------------
    def open(self) -> str:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.slave_path = os.ttyname(self._slave)
        if self.link:
            with contextlib.suppress(FileNotFoundError):
                self.link.unlink()
            self.link.symlink_to(self.slave_path)
        if self.control_path:
            with contextlib.suppress(FileNotFoundError):
                self.control_path.unlink()
            self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            self._listener.bind(str(self.control_path))
            self._listener.listen(4)
            self._listener.setblocking(False)
        return self.slave_path

    def close(self) -> None:
        self._unplug()
        for sock in list(self._clients):
            sock.close()
        self._clients.clear()
        if self._listener is not None:
            self._listener.close()
            self._listener = None
            with contextlib.suppress(FileNotFoundError):
                self.control_path.unlink()

    def serve_forever(self) -> None:
        self.running = True
        if self.clock == "external":
            while self.running:
                self._status_due()  # the first report after a HELLO; later ones come from advance()
                self._wait_io(0.05)
            return
        wall0 = time.monotonic()
        board0 = self.physics.time_s
        max_steps = max(1, int(0.05 * self.speed / self.dt))
        while self.running:
            now = time.monotonic()
            goal = board0 + (now - wall0) * self.speed
            steps = 0
            while self.physics.time_s + self.dt <= goal:
                self.physics.step(self.dt)
                self._run_scheduled()
                steps += 1
                if steps >= max_steps:  # overloaded: let board time lag, not spiral
                    wall0, board0 = now, self.physics.time_s
                    break
            self._maybe_send_status(now)
            self._wait_io(0.002)

    # ---- I/O --------------------------------------------------------------------------
    def _wait_io(self, timeout: float) -> None:
        readers: list = list(self._clients)
        if self._master >= 0:
            readers.append(self._master)
        if self._listener is not None:
            readers.append(self._listener)
        ready, _, _ = select.select(readers, [], [], timeout)
        for r in ready:
            if r == self._master:
                self._read_line()
            elif r is self._listener:
                with contextlib.suppress(BlockingIOError):
                    sock, _ = self._listener.accept()
                    sock.setblocking(False)
                    self._clients[sock] = bytearray()
            else:
                self._read_control(r)

    def _read_line(self) -> None:
        try:
            data = os.read(self._master, 4096)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:
                return
            raise
        for frame in self._decoder.feed(data):
            self._handle(frame)

    def _send(self, msg: messages.Message) -> None:
        if self._master < 0 or self.silent:
            return
        data = codec.encode(msg, self._seq)
        self._seq = (self._seq + 1) & 0xFF
        if self.corrupt_rate > 0:
            buf = bytearray(data)
            for i in range(len(buf)):
                if self._rng.random() < self.corrupt_rate:
                    buf[i] = self._rng.randrange(256)
            data = bytes(buf)
        try:
            written = os.write(self._master, data)
        except (BlockingIOError, OSError):
            written = 0
        self.dropped_bytes += len(data) - written

    def _maybe_send_status(self, now: float) -> None:
        if not self._hello or self.physics.time_s < self._next_status:
            return
        if now - self._last_status_wall < self.min_status_wall_s:
            return
        self._last_status_wall = now
        self._next_status = self.physics.time_s + self._period_s
        self._send_status()

    def _status_due(self) -> None:
        """External clock: a STATUS whenever board time reaches the next report time (no wall
        throttle, so the reports are the same whatever the machine's load)."""
        if self._hello and self.physics.time_s >= self._next_status - 1e-9:
            self._next_status = self.physics.time_s + self._period_s
            self._send_status()

    def advance(self, to_s: float) -> float:
        """External clock: step board time up to ``to_s`` (faults and STATUS fall due on the
        way); a time behind the board's holds it. Returns the board time."""
        if self.clock != "external":
            raise ValueError(
                "the board runs on the wall clock; start it with --clock external to feed it time"
            )
        to_s = float(to_s)
        if not math.isfinite(to_s):
            raise ValueError(f"advance: time must be a finite number of seconds, got {to_s!r}")
        ahead = to_s - self.physics.time_s
        if ahead > MAX_ADVANCE_S:
            raise ValueError(
                f"advance: {to_s:g} s is {ahead:g} s ahead of board time {self.physics.time_s:g} s "
                f"(at most {MAX_ADVANCE_S:g} s per request)"
            )
        if self.clock_s is None or to_s > self.clock_s:
            self.clock_s = to_s
        self._status_due()
        while self.physics.time_s + self.dt <= to_s + 1e-9:
            self.physics.step(self.dt)
            self._run_scheduled()
            self._status_due()
        return self.physics.time_s

    def _send_status(self) -> None:
        self._send(
            messages.Status(
                self.board_time_ms(),
                self._last_cmd_seq,
                messages.STATUS_FLAG_SIMULATED,
                self.physics.reports(),
            )
        )

    def board_time_ms(self) -> int:
        return round(self.physics.time_s * 1000) & 0xFFFFFFFF

    # ---- protocol ---------------------------------------------------------------------
    def _handle(self, frame: codec.Frame) -> None:
        msg = frame.message
        t = messages.type_of(msg)
        if t >= 0x80:
            return  # a board message echoed back; not for us
        if isinstance(msg, messages.Hello):
            if msg.version != messages.PROTOCOL_VERSION:
                self._send(messages.Nak(frame.seq, t, NakCode.BAD_VERSION))
                return
            self._hello = True
            self._period_s = msg.status_period_ms / 1000.0 or self.default_period_s
            self._next_status = self.physics.time_s
            self._send(
                messages.HelloReply(
                    messages.PROTOCOL_VERSION,
                    messages.N_LEGS,
                    int(self.capabilities),
                    MAX_PAYLOAD,
                    self.board_time_ms(),
                )
            )
            return
        if not self._hello:
            self._send(messages.Nak(frame.seq, t, NakCode.NO_HELLO))
            return
        self._last_cmd_seq = frame.seq
        if isinstance(msg, messages.Query):
            self._send_status()
            return
        nak = self._apply(msg)
        if nak is None:
            self._send(messages.Ack(frame.seq, t))
        else:
            self._send(messages.Nak(frame.seq, t, nak))

    def _apply(self, msg: messages.Message) -> NakCode | None:
        ph = self.physics
        if isinstance(msg, messages.SetAngle) and not (self.capabilities & Capability.ANGLE_STOP):
            return NakCode.UNSUPPORTED
        legs = legs_in(msg.mask)
        faulted = any(ph.legs[i].state is messages.LegState.FAULT for i in legs)
        if faulted and isinstance(msg, messages.SetFriction | messages.SetAngle):
            return NakCode.FAULTED
        for i in legs:
            if isinstance(msg, messages.SetFriction):
                ph.set_friction(i, msg.target_ma[i])
            elif isinstance(msg, messages.SetAngle):
                ph.set_angle(i, msg.angle_cdeg[i])
            elif isinstance(msg, messages.Loosen):
                ph.loosen(i)
            elif isinstance(msg, messages.Stop):
                ph.stop(i)
        return None

    # ---- faults -----------------------------------------------------------------------
    def _run_scheduled(self) -> None:
        while self.scheduled and self.scheduled[0].at_s <= self.physics.time_s:
            f = self.scheduled.pop(0)
            self.inject(f.kind, f.arg)

    def inject(self, kind: str, arg: float | None = None) -> None:
        if kind in LEG_FAULTS:
            if arg is None or not 0 <= int(arg) < messages.N_LEGS:
                raise ValueError(f"fault {kind} needs a leg 0..3")
            self.physics.inject(kind, int(arg))
        elif kind == "silent":
            self.silent = True
        elif kind == "corrupt":
            self.corrupt_rate = 1.0 if arg is None else float(arg)
        elif kind == "unplug":
            self._unplug()
        else:
            raise ValueError(f"unknown fault {kind!r}")

    def clear_faults(self) -> None:
        self.physics.clear_faults()
        self.silent = False
        self.corrupt_rate = 0.0

    def _unplug(self) -> None:
        self.unplugged = True
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1
        if self.link is not None:
            with contextlib.suppress(FileNotFoundError):
                self.link.unlink()

    # ---- control channel --------------------------------------------------------------
    def _read_control(self, sock: socket.socket) -> None:
        try:
            data = sock.recv(65536)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            sock.close()
            del self._clients[sock]
            return
        buf = self._clients[sock]
        buf += data
        while b"\n" in buf:
            line, _, rest = bytes(buf).partition(b"\n")
            buf[:] = rest
            try:
                reply = self.control(json.loads(line))
            except (ValueError, KeyError, TypeError, IndexError) as exc:
                reply = {"ok": False, "error": str(exc)}
            with contextlib.suppress(OSError):
                sock.setblocking(True)
                sock.sendall(json.dumps(reply).encode() + b"\n")
                sock.setblocking(False)

    def control(self, req: dict) -> dict:
        """One control-channel request (a decoded JSON object) → its reply."""
        op = req["op"]
        if op == "state":
            return {"ok": True, **self.state()}
        if op == "advance":
            self.advance(req["to_s"])
            return {"ok": True, **self.state()}
        if op == "set_angles":
            for i, deg in enumerate(req["deg"]):
                if deg is not None:
                    self.physics.set_joint_angle(i, float(deg))
            return {"ok": True, "time_s": self.physics.time_s}
        if op == "fault":
            kind = req["kind"]
            self.inject(kind, req.get("leg", req.get("rate")))
            return {"ok": True, "time_s": self.physics.time_s}
        if op == "clear":
            self.clear_faults()
            return {"ok": True}
        if op == "quit":
            self.running = False
            return {"ok": True}
        raise ValueError(f"unknown op {op!r}")

    def state(self) -> dict:
        ph = self.physics
        legs = []
        for i, lg in enumerate(ph.legs):
            legs.append(
                {
                    "state": lg.state.name,
                    "fault": lg.fault.name,
                    "angle_deg": lg.angle_deg,
                    "stop_deg": lg.stop_deg,
                    "torque_nm": ph.friction_torque_nm(i),
                    "current_ma": lg.current * 1000.0,
                    "target_ma": lg.target_a * 1000.0,
                    "travel_mm": lg.travel * 1000.0,
                }
            )
        return {
            "time_s": ph.time_s,
            "speed": self.speed,
            "clock": self.clock,
            "clock_s": self.clock_s,
            "silent": self.silent,
            "corrupt_rate": self.corrupt_rate,
            "unplugged": self.unplugged,
            "legs": legs,
        }
