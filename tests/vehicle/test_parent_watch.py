"""A launcher that dies takes its simulators with it (real processes, SIGKILL of the launcher)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from slopelander_sitl.vehicle.launch import REPO, child_env

LAUNCHER = """
import multiprocessing.forkserver, sys, time
from slopelander_sitl import processes
if sys.argv[1] == "forkserver":
    processes.use_forkserver()
from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle
board = start_legboard(clock="external")
vehicle = start_vehicle(speed=1.0, legboard_control=board.control)
server = multiprocessing.forkserver._forkserver._forkserver_pid if sys.argv[1] == "forkserver" else None
print(vehicle.proc.pid, board.proc.pid, *([server] if server else []), flush=True)
time.sleep(600)
"""


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie waiting for its (dead) parent's reaper counts as ended
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.parametrize("how", ["fresh", "forkserver"])
def test_simulators_end_when_their_launcher_is_killed(how: str):
    """Started fresh, or forked from the forkserver (src/slopelander_sitl/processes.py): the forkserver
    ends with
    its launcher, and its children with it."""
    env = child_env()
    env.pop("SLOPELANDER_PARENT_PID")  # the launcher itself is not watched
    launcher = subprocess.Popen(
        [sys.executable, "-c", LAUNCHER, how], stdout=subprocess.PIPE, text=True, env=env, cwd=REPO
    )
    try:
        line = launcher.stdout.readline()
        pids = [int(p) for p in line.split()]
        assert len(pids) == (3 if how == "forkserver" else 2), line  # the forkserver too: it must end
        time.sleep(1.0)
        assert all(alive(p) for p in pids), "the simulators should run while their launcher lives"
        launcher.send_signal(signal.SIGKILL)  # no clean-up runs in the launcher
        launcher.wait()
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and any(alive(p) for p in pids):
            time.sleep(0.1)
        left = [p for p in pids if alive(p)]
        assert not left, f"simulators still running after their launcher died: {left}"
    finally:
        if launcher.poll() is None:
            launcher.kill()
        for p in pids if "pids" in locals() else []:
            if alive(p):
                os.kill(p, signal.SIGKILL)


def test_a_simulator_started_by_hand_is_not_watched():
    from slopelander_sitl.parent_watch import ENV, watch_parent

    saved = os.environ.pop(ENV, None)
    try:
        assert watch_parent() is None
        os.environ[ENV] = str(os.getpid())  # not this process's parent: someone else's variable
        assert watch_parent() is None
    finally:
        os.environ.pop(ENV, None)
        if saved is not None:
            os.environ[ENV] = saved
