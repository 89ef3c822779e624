"""MAVProxy, the ground station users know, connects to the vehicle, sees its mode, changes it,
arms, reads and sets a parameter."""

from __future__ import annotations

import shutil
import subprocess
import time

import pytest

from sitl.vehicle.launch import start_vehicle
from tests.vehicle.conftest import ROUTE_A

pytestmark = pytest.mark.skipif(shutil.which("mavproxy.py") is None, reason="MAVProxy is not installed")


def test_mavproxy_mode_arm_param(tmp_path):
    v = start_vehicle(params=ROUTE_A, no_script=True)
    try:
        cmd = [
            "mavproxy.py",
            "--master",
            v.mavlink_url,
            "--nowait",
            "--default-modules=link,mode,arm,param",
            "--state-basedir",
            str(tmp_path),
        ]
        p = subprocess.Popen(
            cmd,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=tmp_path,
        )
        time.sleep(4)
        for c in (
            "mode GUIDED",
            "arm throttle",
            "param fetch MOT_PWM_MIN",
            "param set GUID_TIMEOUT 2.5",
            "param fetch GUID_TIMEOUT",
        ):
            p.stdin.write(c + "\n")
            p.stdin.flush()
            time.sleep(1.5)
        p.terminate()
        out, _ = p.communicate(timeout=10)
    finally:
        assert v.stop() == 0  # SIGTERM ends the vehicle cleanly
    assert "Detected vehicle 1:1" in out
    assert "Mode STABILIZE" in out
    assert "DO_SET_MODE: ACCEPTED" in out and "Mode GUIDED" in out
    assert "COMPONENT_ARM_DISARM: ACCEPTED" in out and "ARMED" in out
    assert "MOT_PWM_MIN = 1525.0" in out
    assert "GUID_TIMEOUT = 2.5" in out
