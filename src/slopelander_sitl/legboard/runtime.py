"""Where the simulated board's firmware runs: in this CPython process, or on MicroPython.

The firmware (``firmware/legboard``, package ``legfw``) is the board's own code; the simulated
board runs it with the plant model behind its HAL. With ``SLOPELANDER_MICROPYTHON`` naming a
MicroPython unix-port binary it runs there, as a child process that owns the board's end of the
serial line (:mod:`slopelander_sitl.legboard.line`); otherwise in this process. Either way
:class:`Runner` takes the same requests.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
FIRMWARE_DIR = REPO / "firmware" / "legboard"
WIRE_DIR = REPO / "src" / "slopelander" / "legs"
ENV = "SLOPELANDER_MICROPYTHON"
RUNTIMES = ("auto", "cpython", "micropython")
#: MicroPython's heap for the firmware and its plant: about what a Pico leaves free (and a small
#: heap keeps the unix port's garbage collector fast)
HEAP = "192K"
REPLY_TIMEOUT_S = 30.0  # wall seconds the firmware process may take to answer one request

if not (FIRMWARE_DIR / "legfw").is_dir():  # an install without the checkout's firmware folder
    raise ImportError(
        f"the leg-board firmware is not at {FIRMWARE_DIR}: run from a checkout (pip install -e)"
    )
if str(FIRMWARE_DIR) not in sys.path:
    sys.path.insert(0, str(FIRMWARE_DIR))

from legfw.config import Config  # noqa: E402
from legfw.host import (  # noqa: E402 (the firmware folder is on the path from here)
    FAULT_KINDS,
    IO_FAULTS,
    LEG_FAULTS,
    MAX_ADVANCE_S,
    HostBoard,
    parse_fault,
)


def silence_in_wall_time(speed: float) -> dict[str, int]:
    """Firmware settings keeping the companion-silence rule's 10 s (``silence_ms``) in wall time
    for a board run ``speed`` times faster than the wall clock, for ``--config``: at 20x, 10 s
    of board time was a 0.5 s pause of a loaded machine, and a test board's holding legs
    stopped mid-test (2026-12-07). A test of the rule itself keeps the default."""
    return {"silence_ms": round(Config.silence_ms * max(speed, 1.0))}


__all__ = [
    "FAULT_KINDS",
    "IO_FAULTS",
    "LEG_FAULTS",
    "MAX_ADVANCE_S",
    "HostBoard",
    "MicroPythonChild",
    "Runner",
    "parse_fault",
    "resolve",
    "silence_in_wall_time",
    "start",
]


class RuntimeChoiceError(RuntimeError):
    """The runtime asked for cannot run (no MicroPython binary where it was named)."""


def micropython_binary() -> str | None:
    """The MicroPython named by ``SLOPELANDER_MICROPYTHON`` (None if unset); an error if it is
    set to something that is not an executable file."""
    path = os.environ.get(ENV)
    if not path:
        return None
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        raise RuntimeChoiceError(f"{ENV}={path} is not an executable file")
    return path


def resolve(runtime: str) -> tuple[str, str | None]:
    """``(runtime, binary)``: ``auto`` is MicroPython when ``SLOPELANDER_MICROPYTHON`` is set."""
    if runtime not in RUNTIMES:
        raise RuntimeChoiceError(f"unknown runtime {runtime!r}; one of {', '.join(RUNTIMES)}")
    binary = micropython_binary() if runtime != "cpython" else None
    if runtime == "micropython" and binary is None:
        raise RuntimeChoiceError(f"--runtime micropython needs {ENV} set to a MicroPython binary")
    return ("micropython", binary) if binary else ("cpython", None)


class Runner:
    """The firmware and plant behind one interface: :meth:`control` takes the control
    channel's requests; :attr:`serial_fd` is the descriptor this process must watch for the
    firmware (None when a child process watches it itself)."""

    name = "cpython"
    serial_fd: int | None = None

    def control(self, req: dict) -> dict:
        raise NotImplementedError

    def serial_ready(self) -> None:
        """Bytes arrived on :attr:`serial_fd`."""

    def close(self) -> None:
        """End the firmware."""


class InProcess(Runner):
    """The firmware on this CPython interpreter."""

    def __init__(self, fd: int, **kw) -> None:
        self.board = HostBoard(fd, **kw)
        self.serial_fd = fd

    def control(self, req: dict) -> dict:
        reply = self.board.control(req)
        if self.board.hal.port is None:
            self.serial_fd = None
        return reply

    def serial_ready(self) -> None:
        self.board.serial_ready()

    def close(self) -> None:
        if self.board.hal.port is not None:
            self.board.hal.unplug()
        self.serial_fd = None


class MicroPythonChild(Runner):
    """The firmware on MicroPython, in a child process that owns the board's end of the line."""

    name = "micropython"

    def __init__(
        self,
        binary: str,
        fd: int,
        *,
        config: dict,
        plant: dict,
        seed: int,
        board_id: bytes,
        capabilities: int,
        faults: tuple,
    ) -> None:
        cmd = [binary, "-X", f"heapsize={HEAP}", str(FIRMWARE_DIR / "host_main.py"), str(WIRE_DIR)]
        cmd += [
            "--fd",
            str(fd),
            "--seed",
            str(seed),
            "--board-id",
            board_id.hex(),
            "--caps",
            str(capabilities),
        ]
        cmd += ["--config", json.dumps(config), "--plant", json.dumps(plant)]
        for kind, arg, at in faults:
            cmd += ["--fault", kind + (f":{arg:g}" if arg is not None else "") + f"@{at:g}"]
        self._err = tempfile.TemporaryFile()  # noqa: SIM115 (read back if the child dies)
        self.proc = subprocess.Popen(
            cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._err, pass_fds=[fd], bufsize=0
        )
        self._buf = b""
        ready = self._reply()
        if not ready.get("ready"):
            raise RuntimeError(f"the firmware on MicroPython did not start: {ready}")

    def _reply(self) -> dict:
        deadline = time.monotonic() + REPLY_TIMEOUT_S
        out = self.proc.stdout.fileno()
        while b"\n" not in self._buf:
            left = deadline - time.monotonic()
            ready, _, _ = select.select([out], [], [], max(0.0, left))
            chunk = os.read(out, 65536) if ready else b""
            if not chunk:
                raise self._gone()
            self._buf += chunk
        line, _, self._buf = self._buf.partition(b"\n")
        try:
            return json.loads(line)
        except ValueError:
            raise RuntimeError(f"the firmware on MicroPython wrote {line[:200]!r}, not a reply") from None

    def _gone(self) -> RuntimeError:
        """The child ended or hangs: an error with what it wrote to stderr."""
        self.proc.poll()
        why = "did not answer" if self.proc.returncode is None else f"ended ({self.proc.returncode})"
        self._err.seek(0)
        tail = self._err.read()[-2000:].decode(errors="replace")
        return RuntimeError(f"the firmware on MicroPython {why}: {tail.strip()}")

    def control(self, req: dict) -> dict:
        try:
            self.proc.stdin.write(json.dumps(req).encode() + b"\n")
        except BrokenPipeError:
            raise self._gone() from None
        return self._reply()

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.close()  # the child ends when its stdin does
                self.proc.wait(2.0)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()
        self.proc.stdout.close()
        self._err.close()


def start(runtime: str, fd: int, **kw) -> Runner:
    """The firmware on ``runtime`` (see :func:`resolve`) with the line's board end ``fd``; this
    process keeps ``fd`` only when the firmware runs in it."""
    name, binary = resolve(runtime)
    Config(**kw.get("config", {}))  # a wrong setting named here (ValueError), on either runtime
    if name == "micropython":
        try:
            return MicroPythonChild(binary, fd, **kw)
        finally:
            os.close(fd)  # the child has its own copy
    return InProcess(fd, **kw)
