"""A simulator started by a program ends when that program ends.

The launchers (``slopelander_sitl.vehicle.launch``, ``slopelander_sitl.json_physics.launch``) put their own
process id in
``SLOPELANDER_PARENT_PID``. A child that finds it watches its parent: a test run, demo or benchmark
that is killed (or a pipe into ``head`` that closes) would otherwise leave a simulator spinning a
core for hours. Started by hand from a shell, without the variable, a simulator runs until stopped.
"""

from __future__ import annotations

import os
import signal
import threading
import time

ENV = "SLOPELANDER_PARENT_PID"
#: how often the parent is looked for (s), and how long a clean stop may take before a hard exit
PERIOD_S = 0.5
GRACE_S = 5.0


def parent_gone(expected: int) -> bool:
    """Whether this process's parent is no longer ``expected`` (it was re-parented on its death)."""
    return os.getppid() != expected


def watch_parent(period_s: float = PERIOD_S, grace_s: float = GRACE_S) -> threading.Thread | None:
    """If ``SLOPELANDER_PARENT_PID`` names this process's parent, watch it from a daemon thread:
    once it is gone, send this process SIGTERM (its own handler stops it cleanly), and exit hard
    if it is still running ``grace_s`` later. Returns the thread, or None when not launched so."""
    try:
        expected = int(os.environ.get(ENV, ""))
    except ValueError:
        return None
    if parent_gone(expected):  # started by something else that passed its environment on
        return None

    def run() -> None:
        while not parent_gone(expected):
            time.sleep(period_s)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(grace_s)
        os._exit(1)

    t = threading.Thread(target=run, name="parent-watch", daemon=True)
    t.start()
    return t
