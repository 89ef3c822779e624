"""Simulators forked from the multiprocessing forkserver (src/slopelander_sitl/processes.py) answer as freshly
started ones do: the caller's arguments, environment, working directory and streams; exit status,
time-outs and signals as ``subprocess.Popen`` reports them (real processes, real signals)."""

from __future__ import annotations

import json
import multiprocessing
import multiprocessing.forkserver
import signal
import socket
import subprocess
import sys

import pytest

from slopelander_sitl import processes
from slopelander_sitl.vehicle.launch import REPO, child_env

PROBE = "tests.vehicle.process_probe"


@pytest.fixture
def forked(monkeypatch):
    """:func:`slopelander_sitl.processes.start` forking from this process's forkserver (the one the suite's
    simulators use, or, with SLOPELANDER_FORKSERVER=0, one that preloads nothing)."""
    monkeypatch.setattr(processes, "_CONTEXT", multiprocessing.get_context("forkserver"))
    return processes.start


def forkserver_pid() -> int:
    return multiprocessing.forkserver._forkserver._forkserver_pid


def test_a_forked_module_gets_the_callers_arguments_environment_and_streams(forked, tmp_path):
    env = {**child_env(), "PROBE_VALUE": "seen"}
    with open(tmp_path / "stderr.txt", "w+") as err:
        p = forked(PROBE, ["7", "two words"], env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=err)
        said = json.loads(p.stdout.readline())
        assert p.wait(30) == 7
        assert p.poll() == 7 and p.returncode == 7
        err.seek(0)
        assert err.read() == "to stderr\n"
    cmdline = said.pop("cmdline")
    assert "-c" in cmdline and any("multiprocessing.forkserver" in a for a in cmdline)  # forked, not exec'd
    assert said.pop("interfaces") == sorted(name for _, name in socket.if_nameindex())
    said.pop("warm")
    assert said == {
        "argv": ["7", "two words"],
        "cwd": str(tmp_path),
        "env": "seen",
        "pid": p.pid,
        "ppid": forkserver_pid(),  # its parent, which reaps it and reports its status
    }


def test_time_outs_and_signals_are_reported_as_popen_reports_them(forked, tmp_path):
    def sleeper():
        p = forked(
            PROBE, ["sleep"], env=child_env(), cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL
        )
        assert json.loads(p.stdout.readline())["argv"] == ["sleep"]
        return p

    p = sleeper()
    assert p.poll() is None
    with pytest.raises(subprocess.TimeoutExpired):
        p.wait(0.3)
    p.terminate()
    assert p.wait(10) == -signal.SIGTERM
    q = sleeper()
    q.kill()
    assert q.wait(10) == -signal.SIGKILL
    q.kill()  # a child already reaped is not signalled again (its pid may be someone else's)
    assert q.returncode == -signal.SIGKILL


def test_a_module_that_fails_at_once_reports_its_status_and_stream(forked, tmp_path):
    with open(tmp_path / "stderr.txt", "w+") as err:
        p = forked(
            "slopelander_sitl.vehicle",
            ["--speed", "-1"],
            env=child_env(),
            cwd=tmp_path,
            stdout=subprocess.PIPE,
            stderr=err,
        )
        assert p.stdout.read() == ""
        assert p.wait(60) == 2
        err.seek(0)
        assert "--speed -1.0 must be >= 0" in err.read()


def _skip_where_only_loopback() -> None:
    if sorted(name for _, name in socket.if_nameindex()) == ["lo"]:
        pytest.skip("this machine has only loopback: isolation cannot be told apart")


def test_an_isolated_child_has_only_loopback_and_what_it_starts_shares_it(forked, tmp_path):
    """ArduCopter's pod: forked into a loopback-only network namespace of its own (as ``unshare
    -rn`` would start it); what it starts (its physics) is a fresh interpreter in that namespace,
    whose output and status reach it as from Popen."""
    _skip_where_only_loopback()
    p = forked(
        PROBE,
        ["start"],
        env=child_env(),
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        isolate=True,
    )
    said = json.loads(p.stdout.readline())
    assert p.wait(60) == 0
    assert said["interfaces"] == ["lo"]
    child = said["child"]
    assert child["interfaces"] == ["lo"]  # the grandchild shares its parent's namespace
    assert child["ppid"] == said["pid"] and child["argv"] == ["5"] and said["child_status"] == 5
    assert child["cmdline"][1:3] == ["-m", PROBE]


def test_without_the_forkserver_an_isolated_module_is_started_through_unshare(tmp_path, monkeypatch):
    """A user's demo: no forkserver, so ``unshare -rn python -m ...``; the same namespace rule."""
    _skip_where_only_loopback()
    monkeypatch.setattr(processes, "_CONTEXT", None)
    p = processes.start(
        PROBE,
        ["start"],
        env=child_env(),
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        isolate=True,
    )
    out, _ = p.communicate(timeout=60)
    said = json.loads(out)
    assert p.returncode == 0
    assert said["interfaces"] == ["lo"] and said["cmdline"][1:3] == ["-m", PROBE]
    assert said["child"]["interfaces"] == ["lo"] and said["child"]["cmdline"][1:3] == ["-m", PROBE]
    assert said["child_status"] == 5


LAUNCHER = """
import subprocess, sys
from slopelander_sitl import processes
from slopelander_sitl.vehicle.launch import child_env
processes.use_forkserver()
quiet = subprocess.DEVNULL
p = processes.start(sys.argv[1], ["0"], env=child_env(), cwd=".", stdout=subprocess.PIPE, stderr=quiet)
print(p.stdout.readline(), end="")
p.wait(60)
"""


def test_use_forkserver_forks_from_a_process_with_the_simulators_loaded():
    """What the test suite turns on: the forkserver preloads slopelander_sitl.warm (the simulators' modules
    and
    the compiled model), so a forked child starts with them loaded."""
    env = child_env()
    env.pop("SLOPELANDER_PARENT_PID")
    done = subprocess.run(
        [sys.executable, "-c", LAUNCHER, PROBE],
        capture_output=True,
        text=True,
        env=env,
        cwd=REPO,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    said = json.loads(done.stdout)
    assert said["warm"] is True and any("multiprocessing.forkserver" in a for a in said["cmdline"])
