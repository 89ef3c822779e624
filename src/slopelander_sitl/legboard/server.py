"""The simulated board as a process: the board's firmware, on a pseudo-terminal, over a plant.

It makes the pty, runs the firmware (``firmware/legboard``) with the plant model behind its
HAL — on MicroPython when ``SLOPELANDER_MICROPYTHON`` names one, else in this process (see
:mod:`slopelander_sitl.legboard.runtime`) — and serves the control channel (a UNIX socket, JSON lines)
through which tests inject faults and the vehicle simulator feeds joint angles and time.

Board time follows one of two clocks. ``wall`` (the default, for a board used on its own):
``speed`` × wall time. ``external`` (a board a simulated vehicle drives): only the times the
vehicle sends (control op ``advance``), so board and vehicle cannot drift apart under machine
load; a board fed no time stands still, sends no periodic STATUS and only answers commands.
The firmware itself never reads a clock: this process feeds it time either way. Nor does it
touch the pty: it reads and writes a socket that :mod:`slopelander_sitl.legboard.line` relays to
the pty's master side (that module says why).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import select
import socket
import time
import tty
from dataclasses import dataclass
from pathlib import Path

from slopelander.legs.messages import Capability
from slopelander_sitl.legboard import runtime
from slopelander_sitl.legboard.line import PtyLine
from slopelander_sitl.legboard.runtime import (
    FAULT_KINDS,
    IO_FAULTS,
    LEG_FAULTS,
    MAX_ADVANCE_S,
    Runner,
    parse_fault,
)

CLOCKS = ("wall", "external")
TICK_S = 0.004  # the firmware's tick (legfw.config.Config.tick_ms)
__all__ = ["CLOCKS", "FAULT_KINDS", "IO_FAULTS", "LEG_FAULTS", "MAX_ADVANCE_S", "BoardServer", "FaultSpec"]


@dataclass(frozen=True)
class FaultSpec:
    """A fault to inject: ``kind``, a leg or a rate as ``arg``, at board time ``at_s``."""

    kind: str
    arg: float | None = None
    at_s: float = 0.0

    @classmethod
    def parse(cls, text: str) -> FaultSpec:
        """``KIND[:ARG][@T]``, e.g. ``stuck:1``, ``corrupt:0.2``, ``unplug@5``."""
        return cls(*parse_fault(text))


def _finite(to_s: object) -> float:
    """A time to feed the board: a finite number of seconds (JSON has no NaN to pass it on)."""
    t = float(to_s)
    if not math.isfinite(t):
        raise ValueError(f"advance: time must be a finite number of seconds, got {to_s!r}")
    return t


class BoardServer:
    """One simulated board: pty, firmware and plant, control channel."""

    def __init__(
        self,
        *,
        link: str | Path | None = None,
        control: str | Path | None = None,
        speed: float = 1.0,
        status_period_ms: int = 100,
        angle_stop: bool = True,
        faults: tuple[FaultSpec, ...] = (),
        seed: int = 0,
        clock: str = "wall",
        runtime: str = "auto",
        board_id: bytes = b"SIMBOARD",
        plant: dict | None = None,
        config: dict | None = None,
    ) -> None:
        if clock not in CLOCKS:
            raise ValueError(f"unknown clock {clock!r}; one of {', '.join(CLOCKS)}")
        self.clock = clock
        self.link = Path(link) if link else None
        self.control_path = Path(control) if control else (Path(f"{self.link}.ctl") if self.link else None)
        self.speed = speed
        #: what the board says it can do; the SIMULATED bit is the board's own claim (a test may
        #: take it away to stand in for a real board) and sets STATUS's "simulated" flag
        self.capabilities = int(Capability.SIMULATED | (Capability.ANGLE_STOP if angle_stop else 0))
        self.faults = tuple(faults)
        self.seed = seed
        self.runtime = runtime
        self.board_id = board_id
        self.plant = dict(plant or {})
        self.config = {"status_ms": status_period_ms, **(config or {})}
        self.running = False
        self.unplugged = False
        self.slave_path = ""
        self.runner: Runner | None = None
        self.line: PtyLine | None = None
        self._slave = -1
        self._listener: socket.socket | None = None
        self._clients: dict[socket.socket, bytearray] = {}

    # ---- life cycle -------------------------------------------------------------------
    def open(self) -> str:
        master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.slave_path = os.ttyname(self._slave)
        config = dict(self.config, angle_stop=bool(self.capabilities & Capability.ANGLE_STOP))
        self.line = PtyLine(master)  # the firmware never waits on the tty layer (see line.py)
        self.runner = runtime.start(
            self.runtime,
            self.line.board_end(),
            config=config,
            plant=self.plant,
            seed=self.seed,
            board_id=self.board_id,
            capabilities=self.capabilities & Capability.SIMULATED,
            faults=tuple((f.kind, f.arg, f.at_s) for f in self.faults),
        )
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
        with contextlib.suppress(RuntimeError, OSError):  # a firmware process already gone
            self._unplug()
        if self.runner is not None:
            self.runner.close()
            self.runner = None
        if self.line is not None:
            self.line.close()
            self.line = None
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
                self._wait_io(0.05)
            return
        wall0 = time.monotonic()
        board0 = self.time_s()
        chunk = max(TICK_S, 0.05 * self.speed)  # board seconds one step may take at most
        while self.running:
            now = time.monotonic()
            goal = board0 + (now - wall0) * self.speed
            if goal - self._time >= TICK_S:  # a firmware tick is due
                reached = self._run({"op": "advance", "to_s": min(goal, self._time + chunk), "reply": "time"})
                if goal - reached["time_s"] > chunk:  # overloaded: let board time lag, not spiral
                    wall0, board0 = now, reached["time_s"]
            wait = (self._time + TICK_S - goal) / self.speed  # wall seconds to the next tick
            self._wait_io(min(0.01, max(0.0005, wait)))

    # ---- the firmware -----------------------------------------------------------------
    _time = 0.0

    def time_s(self) -> float:
        return self._run({"op": "state"})["time_s"]

    def _run(self, req: dict) -> dict:
        reply = self.runner.control(req)
        if "time_s" in reply:
            self._time = reply["time_s"]
        if reply.get("unplugged") and not self.unplugged:  # a scheduled ``unplug`` fell due
            self._unplug(firmware_knows=True)
        return reply

    def advance(self, to_s: float) -> float:
        """External clock: step board time up to ``to_s`` (faults and STATUS fall due on the
        way); a time behind the board's holds it. Returns the board time."""
        if self.clock != "external":
            raise ValueError(
                "the board runs on the wall clock; start it with --clock external to feed it time"
            )
        return self._checked({"op": "advance", "to_s": _finite(to_s), "reply": "time"})["time_s"]

    def _checked(self, req: dict) -> dict:
        reply = self._run(req)
        if not reply.get("ok"):
            raise ValueError(reply.get("error", "refused"))
        return reply

    # ---- I/O --------------------------------------------------------------------------
    def _wait_io(self, timeout: float) -> None:
        readers: list = list(self._clients)
        serial = self.runner.serial_fd if self.runner is not None else None
        if serial is not None:
            readers.append(serial)
        if self._listener is not None:
            readers.append(self._listener)
        ready, _, _ = select.select(readers, [], [], timeout)
        for r in ready:
            if r == serial:
                self.runner.serial_ready()
            elif r is self._listener:
                with contextlib.suppress(BlockingIOError):
                    sock, _ = self._listener.accept()
                    sock.setblocking(False)
                    self._clients[sock] = bytearray()
            else:
                self._read_control(r)

    def _unplug(self, firmware_knows: bool = False) -> None:
        """The link goes: like a pulled USB cable, the device and its name disappear."""
        if self.runner is not None and not self.unplugged and not firmware_knows:
            self.unplugged = True
            self.runner.control({"op": "fault", "kind": "unplug"})  # the firmware's side closes
        self.unplugged = True
        if self._slave >= 0:
            os.close(self._slave)
            self._slave = -1
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
        if op == "quit":
            self.running = False
            return {"ok": True}
        if op == "advance":
            if self.clock != "external":
                raise ValueError(
                    "the board runs on the wall clock; start it with --clock external to feed it time"
                )
            req = dict(req, to_s=_finite(req["to_s"]))
        if op == "line_stall":  # the pty's bytes held, both ways, as a loaded kernel holds them
            if self.line is None:
                raise ValueError("line_stall: the board has no line open")
            self.line.stall(float(req["seconds"]))
            return {"ok": True, "time_s": self._time}
        if op == "fault" and req.get("kind") == "unplug":
            self._unplug()
            return {"ok": True, "time_s": self._time}
        reply = self._run(req)
        if op in ("state", "advance"):
            reply.update(
                speed=self.speed, clock=self.clock, runtime=self.runner.name, unplugged=self.unplugged
            )
        return reply

    def state(self) -> dict:
        return self.control({"op": "state"})
