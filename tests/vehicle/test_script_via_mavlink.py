"""The on-board script inside the vehicle, driven over MAVLink: its own COMMAND_ACK for
MAV_CMD_USER_1, the motor outputs it commands (1500 stop, 1000 full and 1250 half reverse),
the mixer taking the outputs back when the validity lapses, refusal while disarmed."""

from __future__ import annotations

import pytest
from pymavlink import mavutil

from slopelander_sitl.vehicle.launch import REPO, start_vehicle
from tests.vehicle.conftest import ROUTE_A
from tests.vehicle.flying import M, arm, command, set_interval, set_mode, wait_msg

SCRIPT = REPO / "firmware_params" / "scripts" / "slopelander.lua"
USER_1, USER_2 = 31010, 31011


@pytest.fixture(scope="module")
def scripted():
    v = start_vehicle(params=ROUTE_A, script=SCRIPT, speed=1.0)
    conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255, source_component=190)
    try:
        assert conn.wait_heartbeat(timeout=10) is not None
        yield conn
    finally:
        conn.close()
        v.stop()


def _servos(conn, cond) -> tuple[int, ...]:
    m = wait_msg(
        conn, "SERVO_OUTPUT_RAW", lambda m: cond((m.servo1_raw, m.servo2_raw, m.servo3_raw, m.servo4_raw))
    )
    return m.servo1_raw, m.servo2_raw, m.servo3_raw, m.servo4_raw


def test_script_commands_outputs(scripted):
    conn = scripted
    wait_msg(conn, "NAMED_VALUE_FLOAT", lambda m: m.name == "SL_STATE")
    # contract 4: param 7 is a request number
    assert (
        command(conn, USER_1, 2, 100, 1000, 0, 0, 0, 1).result == M.MAV_RESULT_TEMPORARILY_REJECTED
    )  # disarmed
    set_interval(conn, M.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW, 50)
    assert set_mode(conn, 4).result == M.MAV_RESULT_ACCEPTED
    assert arm(conn).result == M.MAV_RESULT_ACCEPTED
    # a commanded reverse needs the range at or below an armed cut height: set up and arm the
    # reflex, then abort it before it could cut (on the ground a chain counts after 600 ms)
    assert command(conn, USER_2, 3, 0, 0.5, 0, 0, 0, 2).result == M.MAV_RESULT_ACCEPTED
    assert command(conn, USER_2, 1, 0.3, 20, 100, 500, 1000, 3).result == M.MAV_RESULT_ACCEPTED
    assert command(conn, USER_2, 0, 0, 0, 0, 0, 0, 4).result == M.MAV_RESULT_ACCEPTED
    for n, (action, pct, pwm) in enumerate(((1, 0, 1500), (2, 100, 1000), (2, 50, 1250))):
        ack = command(conn, USER_1, action, pct, 2000, 0, 0, 0, 10 + n)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        assert _servos(conn, lambda s, p=pwm: all(x == p for x in s))
    assert command(conn, USER_1, 7, 0, 1000, 0, 0, 0, 20).result == M.MAV_RESULT_DENIED  # unknown action
    # the last command lapses after 2 s: the mixer's idle outputs come back (above the ESC deadband)
    assert _servos(conn, lambda s: all(x >= 1525 for x in s))
