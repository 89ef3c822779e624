"""Pre-arm lean-angle check on a 20 deg roof follows ANGLE_MAX; force-arm 2989 bypasses it."""

from __future__ import annotations

import pytest
from pymavlink import mavutil

from slopelander_sitl.vehicle.launch import start_vehicle
from tests.vehicle.conftest import ROUTE_A
from tests.vehicle.flying import M, arm, command, wait_msg


@pytest.fixture(scope="module")
def on_roof():
    v = start_vehicle(
        params=ROUTE_A, no_script=True, speed=2.0, scenario={"slope_deg": 20.0, "start_on": "roof"}
    )
    conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255, source_component=190)
    try:
        assert conn.wait_heartbeat(timeout=10) is not None
        yield conn
    finally:
        conn.close()
        v.stop()


def test_lean_check(on_roof):
    conn = on_roof
    att = wait_msg(conn, "ATTITUDE")
    lean = abs(att.pitch) * 57.2958
    assert 10 < lean < 30, lean  # sitting on the roof, tilted with it
    conn.mav.param_set_send(1, 1, b"ANGLE_MAX", 800.0, M.MAV_PARAM_TYPE_REAL32)
    wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "ANGLE_MAX")
    assert arm(conn).result == M.MAV_RESULT_FAILED
    wait_msg(conn, "STATUSTEXT", lambda m: m.text == "Arm: Leaning")
    conn.mav.param_set_send(1, 1, b"ARMING_CHECK", 0.0, M.MAV_PARAM_TYPE_REAL32)
    wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "ARMING_CHECK")
    assert arm(conn).result == M.MAV_RESULT_ACCEPTED
    command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    conn.mav.param_set_send(1, 1, b"ARMING_CHECK", 1.0, M.MAV_PARAM_TYPE_REAL32)
    wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "ARMING_CHECK")
    # 21196 is the force-DISARM magic: in an arm command it is an ordinary arm, checks and all
    assert command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 1, 21196).result == M.MAV_RESULT_FAILED
    assert arm(conn, force=True).result == M.MAV_RESULT_ACCEPTED
