"""Simulators forked from a warm zygote answer as freshly started ones do: the caller's arguments,
environment, working directory and streams; exit status, time-outs and signals as
``subprocess.Popen`` reports them (real processes, real signals)."""

from __future__ import annotations

import json
import signal
import socket
import subprocess

import pytest

from slopelander_sitl import zygote as zygote_module
from slopelander_sitl.vehicle.launch import child_env
from slopelander_sitl.zygote import Zygote

PROBE = "tests.vehicle.zygote_probe"


@pytest.fixture
def zygote():
    z = Zygote(preload=())  # nothing to warm: the probe imports only the standard library
    yield z
    z.close()


def test_a_forked_module_gets_the_callers_arguments_environment_and_streams(zygote, tmp_path):
    env = {**child_env(), "PROBE_VALUE": "seen"}
    with open(tmp_path / "stderr.txt", "w+") as err:
        p = zygote.spawn(PROBE, ["7", "two words"], env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=err)
        said = json.loads(p.stdout.readline())
        assert p.wait(10) == 7
        assert p.poll() == 7 and p.returncode == 7
        err.seek(0)
        assert err.read() == "to stderr\n"
    assert said.pop("cmdline")[1:3] == ["-m", "slopelander_sitl.zygote"]  # forked, not started afresh
    assert said.pop("interfaces") == sorted(name for _, name in socket.if_nameindex())
    assert said == {
        "argv": ["7", "two words"],
        "cwd": str(tmp_path),
        "env": "seen",
        "pid": p.pid,
        "ppid": zygote._proc.pid,  # its parent, which reaps it and reports its status
    }


def test_time_outs_and_signals_are_reported_as_popen_reports_them(zygote, tmp_path):
    def sleeper():
        p = zygote.spawn(
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


def test_a_module_that_fails_at_once_reports_its_status_and_stream(zygote, tmp_path):
    with open(tmp_path / "stderr.txt", "w+") as err:
        p = zygote.spawn(
            "slopelander_sitl.vehicle",
            ["--speed", "-1"],
            env=child_env(),
            cwd=tmp_path,
            stdout=subprocess.PIPE,
            stderr=err,
        )
        assert p.stdout.read() == ""
        assert p.wait(30) == 2
        err.seek(0)
        assert "--speed -1.0 must be >= 0" in err.read()


def _skip_where_only_loopback() -> None:
    if sorted(name for _, name in socket.if_nameindex()) == ["lo"]:
        pytest.skip("this machine has only loopback: isolation cannot be told apart")


def test_an_isolated_child_has_only_loopback_and_what_it_starts_is_forked_from_it(zygote, tmp_path):
    """ArduCopter's pod: forked from the zygote into a loopback-only network namespace of its own
    (as ``unshare -rn`` would start it), it forks its physics from itself, warm, in the same
    namespace; the grandchild's output, status and end reach the child as from Popen."""
    _skip_where_only_loopback()
    p = zygote.spawn(
        PROBE,
        ["start"],
        env=child_env(),
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        isolate=True,
    )
    said = json.loads(p.stdout.readline())
    assert p.wait(30) == 0
    assert said["interfaces"] == ["lo"]
    child = said["child"]
    assert child["interfaces"] == ["lo"]  # the grandchild shares its parent's namespace
    assert child["ppid"] == said["pid"] and child["argv"] == ["5"] and said["child_status"] == 5
    assert child["cmdline"][1:3] == [
        "-m",
        "slopelander_sitl.zygote",
    ]  # forked from the warm child, not exec'd


def test_without_a_zygote_an_isolated_module_is_started_through_unshare(tmp_path, monkeypatch):
    """A user's demo: no zygote, so ``unshare -rn python -m ...``; the same namespace rule."""
    _skip_where_only_loopback()
    monkeypatch.setattr(zygote_module, "_ZYGOTE", None)
    p = zygote_module.start(
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
    # not a zygote's child, so what it starts is a fresh interpreter too, in its namespace
    assert said["child"]["interfaces"] == ["lo"] and said["child"]["cmdline"][1:3] == ["-m", PROBE]
    assert said["child_status"] == 5


def test_leg_boards_are_forked_before_the_model_is_loaded_and_a_vehicle_after(tmp_path):
    """The zygote loads the compiled model (the heavy modules' ``warm``) only when first asked for
    something other than a leg board: the tests that need no model start leg boards while the
    model still compiles beside them, and a zygote that loaded it then compiled it a second time."""
    z = Zygote()  # the simulators' own modules
    try:
        quiet = {
            "env": child_env(),
            "cwd": tmp_path,
            "stdout": subprocess.DEVNULL,
            "stderr": subprocess.DEVNULL,
        }
        board = z.spawn("slopelander_sitl.legboard", ["--help"], **quiet)
        assert board.wait(30) == 0
        assert board.warm == ("slopelander_sitl.legboard.__main__",)
        probe = z.spawn(PROBE, ["0"], **quiet)
        assert probe.wait(60) == 0
        assert sorted(probe.warm) == sorted(zygote_module.PRELOAD)
    finally:
        z.close()
