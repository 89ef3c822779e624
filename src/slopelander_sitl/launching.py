"""Start a simulator as a child process and wait for its ready line: the one launch sequence the
simulated vehicle's, the JSON physics' and ArduCopter's launchers share.

Each simulator prints one line starting with a known word once it serves (``vehicle ready``,
``json_physics ready``, ``arducopter ready``); anything it says on stderr goes to a file in its
own temporary folder, and becomes the error when it dies before that line.
"""

from __future__ import annotations

import subprocess
import tempfile
import time
from pathlib import Path

from slopelander_sitl import processes
from slopelander_sitl.vehicle.launch import REPO, child_env


class LaunchError(RuntimeError):
    """A simulator ended, or stayed silent, before it said it was ready."""


def start_ready_process(
    module: str,
    argv: list[str],
    ready: str,
    tmp: tempfile.TemporaryDirectory,
    what: str,
    timeout: float,
    cwd: Path = REPO,
    isolate: bool = False,
) -> tuple[subprocess.Popen | processes.ForkedProcess, str]:
    """Run ``python -m module *argv`` (:func:`slopelander_sitl.processes.start`: forked from a warm forkserver
    where this process uses one; ``isolate``: in a loopback-only network namespace of its own), stderr to
    ``<tmp>/stderr.txt``, until it prints a line starting with ``ready``; returns the process and
    that line. On failure the process is killed, ``tmp`` is removed and :class:`LaunchError`
    carries the end of its stderr."""
    err_path = Path(tmp.name) / "stderr.txt"
    with open(err_path, "w") as err:
        proc = processes.start(
            module, argv, env=child_env(), cwd=cwd, stdout=subprocess.PIPE, stderr=err, isolate=isolate
        )
    deadline = time.monotonic() + timeout
    line = ""
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line.startswith(ready) or (not line and proc.poll() is not None):
            break
    if not line.startswith(ready):
        proc.kill()
        proc.wait()
        msg = err_path.read_text().strip()[-2000:]
        tmp.cleanup()
        why = "stayed silent" if proc.returncode in (None, -9) and time.monotonic() >= deadline else "ended"
        raise LaunchError(f"{what} did not start ({why}): {msg or 'no message'}")
    return proc, line.strip()
