"""Against a real ArduCopter SITL binary, only when SLOPELANDER_ARDUCOPTER points at one
(``build/sitl/bin/arducopter`` from ``./waf configure --board sitl && ./waf copter``).

ArduCopter boots on slopelander's physics with the JSON parameter file and the on-board script,
and its own MAVLink shows the physics: level attitude on the pad, the rangefinder reading the
leg height, and the script announcing itself. Run it on a host without other networks or in a
loopback-only network namespace: SITL listens on TCP 5760-5763 on every interface.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from sitl.json_physics.launch import start_json_physics
from sitl.vehicle.launch import REPO

os.environ.setdefault("MAVLINK20", "1")

BINARY = os.environ.get("SLOPELANDER_ARDUCOPTER")


def _binary() -> Path:
    if not BINARY:
        reason = "SLOPELANDER_ARDUCOPTER is not set: no ArduCopter SITL binary to fly against"
        print(reason)
        pytest.skip(reason)
    path = Path(BINARY)
    if not (path.is_file() and os.access(path, os.X_OK)):
        pytest.fail(f"SLOPELANDER_ARDUCOPTER={BINARY} is not an executable file")
    return path


def test_arducopter_flies_on_slopelanders_physics(tmp_path: Path) -> None:
    binary = _binary()
    from pymavlink import mavutil

    (tmp_path / "scripts").mkdir()
    shutil.copy(REPO / "firmware_params" / "scripts" / "slopelander.lua", tmp_path / "scripts")
    srv = start_json_physics(scenario={"noise": {"accel": 0.0, "gyro": 0.0, "range": 0.0}}, port=9002)
    log = open(tmp_path / "arducopter.log", "w")  # noqa: SIM115 - SITL writes it until it stops
    sitl = subprocess.Popen(
        [
            str(binary),
            "--model",
            "JSON:127.0.0.1",
            "--speedup",
            "1",
            "-I0",
            "--defaults",
            str(REPO / "firmware_params" / "sitl-json.parm"),
            "--home",
            "47.3977,8.5456,400,0",
        ],
        cwd=tmp_path,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    conn = None
    try:
        deadline = time.monotonic() + 60
        while conn is None and time.monotonic() < deadline:
            try:
                conn = mavutil.mavlink_connection("tcp:127.0.0.1:5760", source_system=255)
            except OSError:
                time.sleep(0.5)
        assert conn is not None, "SITL did not open TCP 5760"
        assert conn.wait_heartbeat(timeout=30) is not None
        for msg_id in (30, 132):  # ATTITUDE, DISTANCE_SENSOR
            conn.mav.command_long_send(1, 1, 511, 0, msg_id, 100_000, 0, 0, 0, 0, 0)
        seen: dict[str, object] = {}
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and len(seen) < 3:
            m = conn.recv_match(
                type=["ATTITUDE", "DISTANCE_SENSOR", "NAMED_VALUE_FLOAT"], blocking=True, timeout=1
            )
            if m is None:
                continue
            if m.get_type() == "NAMED_VALUE_FLOAT":
                if m.name == "SL_STATE":
                    seen["script"] = m.value
            else:
                seen[m.get_type()] = m
        assert set(seen) == {"ATTITUDE", "DISTANCE_SENSOR", "script"}, seen
        assert abs(seen["ATTITUDE"].pitch) < 0.05 and abs(seen["ATTITUDE"].roll) < 0.05
        assert 5 <= seen["DISTANCE_SENSOR"].current_distance <= 30  # cm: the body a leg's height up
    finally:
        if conn is not None:
            conn.close()
        sitl.terminate()
        try:
            sitl.wait(10)
        except subprocess.TimeoutExpired:
            sitl.kill()
            sitl.wait()
        log.close()
        srv.stop()
    assert "frames=0 " not in srv.summary, srv.summary
