"""A real simulated leg board in its own process, on a real pseudo-terminal.

``sim_board(*flags)`` starts ``python -m slopelander_sitl.legboard`` at a high time scale and returns a
handle; every board a test starts is terminated (then killed if need be) at teardown, its
pipe closed and its temporary directory removed.
"""

from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest

from slopelander_sitl.legboard.control import BoardControl
from slopelander_sitl.legboard.runtime import silence_in_wall_time

ROOT = Path(__file__).resolve().parents[2]
SPEED = 20.0


@dataclass
class SimBoard:
    link: Path
    control: Path
    speed: float
    proc: subprocess.Popen

    def wall(self, board_seconds: float) -> float:
        """Wall seconds to allow for ``board_seconds`` of board time (with margin)."""
        return board_seconds / self.speed * 1.5 + 1.0

    def ctl(self) -> BoardControl:
        return BoardControl(self.control)


def _start(directory: Path, flags: tuple[str, ...], speed: float) -> SimBoard:
    link = directory / "legs"
    config = directory / "config.json"
    config.write_text(json.dumps(silence_in_wall_time(speed)))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), str(ROOT), env.get("PYTHONPATH", "")])
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "slopelander_sitl.legboard",
            "--link",
            str(link),
            "--speed",
            str(speed),
            "--config",
            str(config),
            *flags,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
        start_new_session=True,
    )
    ready, _, _ = select.select([proc.stdout], [], [], 10.0)
    line = proc.stdout.readline().decode() if ready else ""
    if "legboard ready" not in line:
        _stop(proc)
        raise RuntimeError(f"simulated board did not start: {line!r}")
    return SimBoard(link, Path(f"{link}.ctl"), speed, proc)


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=3.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=3.0)
    if proc.stdout is not None:
        proc.stdout.close()


@pytest.fixture(autouse=True)
def no_leaked_fds():
    """Every port, pty, socket and pipe a test opens is closed by its end."""
    before = set(os.listdir("/proc/self/fd"))
    yield
    leaked = set(os.listdir("/proc/self/fd")) - before
    assert not leaked, f"file descriptors left open: {sorted(leaked)}"


@pytest.fixture
def sim_board():
    """Factory: ``sim_board("--fault", "stuck:1", speed=20)`` → a running :class:`SimBoard`."""
    started: list[tuple[subprocess.Popen, str]] = []

    def start(*flags: str, speed: float = SPEED) -> SimBoard:
        directory = tempfile.mkdtemp(prefix="legs-")  # short: UNIX socket paths are limited
        board = _start(Path(directory), flags, speed)
        started.append((board.proc, directory))
        return board

    yield start
    for proc, directory in started:
        _stop(proc)
        shutil.rmtree(directory, ignore_errors=True)


@pytest.fixture
def board(sim_board):
    """A default simulated board."""
    return sim_board()
