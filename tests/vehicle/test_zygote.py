"""Simulators forked from a warm zygote answer as freshly started ones do: the caller's arguments,
environment, working directory and streams; exit status, time-outs and signals as
``subprocess.Popen`` reports them (real processes, real signals)."""

from __future__ import annotations

import json
import signal
import subprocess

import pytest

from sitl.vehicle.launch import child_env
from sitl.zygote import Zygote

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
            "sitl.vehicle",
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
