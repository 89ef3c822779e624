"""ArduCopter's ground rules on the simulated vehicle, on a 20 deg roof: armed in GUIDED it idles at
MOT_SPIN_ARM and stays put (a velocity target does not lift it off: only a take-off does); the
rangefinder changes at 20 Hz; on the roof after a GUIDED descent a ground-station disarm is refused
while the land detector has not fired, a forced disarm is accepted."""

from __future__ import annotations

import itertools

import pytest
from pymavlink import mavutil

from slopelander_sitl.vehicle.launch import start_vehicle
from tests.vehicle.conftest import ROUTE_A
from tests.vehicle.flying import M, command, set_interval, set_mode, velocity, wait_msg

#: its tests share one vehicle on the roof (on_roof): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("vehicle/ground_rules")

SPIN_ARM_PWM = round(1525 + 0.10 * (2000 - 1525))


@pytest.fixture(scope="module")
def on_roof():
    v = start_vehicle(
        params=ROUTE_A, no_script=True, speed=2.0, scenario={"slope_deg": 20.0, "start_on": "roof", "seed": 3}
    )
    conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255, source_component=190)
    try:
        assert conn.wait_heartbeat(timeout=30) is not None
        yield conn
    finally:
        conn.close()
        v.stop()


def _span(conn, kind: str, seconds: float) -> list:
    first = wait_msg(conn, kind)
    out = [first]
    while (out[-1].time_boot_ms - first.time_boot_ms) / 1000.0 < seconds:
        out.append(wait_msg(conn, kind))
    return out


def test_armed_on_the_roof_idles_and_stays_put_until_take_off(on_roof):
    conn = on_roof
    set_interval(conn, M.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW, 20)
    assert set_mode(conn, 4).result == M.MAV_RESULT_ACCEPTED
    assert command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
    start = wait_msg(conn, "LOCAL_POSITION_NED")
    for _ in range(10):  # a climb target on the ground is not a take-off in GUIDED
        velocity(conn, 0.0, -1.0)
        wait_msg(conn, "SERVO_OUTPUT_RAW")
    pos = _span(conn, "LOCAL_POSITION_NED", 4.0)
    outs = [wait_msg(conn, "SERVO_OUTPUT_RAW") for _ in range(20)]
    assert {(o.servo1_raw, o.servo2_raw, o.servo3_raw, o.servo4_raw) for o in outs} == {(SPIN_ARM_PWM,) * 4}
    assert max(abs(p.x - start.x) for p in pos) < 0.01, [p.x for p in pos]
    assert max(abs(p.z - start.z) for p in pos) < 0.01
    command(conn, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW, -1)
    assert command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == M.MAV_RESULT_ACCEPTED  # landed


def test_rangefinder_changes_at_20_hz(on_roof):
    conn = on_roof
    set_interval(conn, M.MAVLINK_MSG_ID_DISTANCE_SENSOR, 100)
    msgs = _span(conn, "DISTANCE_SENSOR", 2.0)
    command(conn, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_DISTANCE_SENSOR, -1)
    changes = [
        b.time_boot_ms for a, b in itertools.pairwise(msgs) if b.current_distance != a.current_distance
    ]
    gaps = [b - a for a, b in itertools.pairwise(changes)]
    assert len(msgs) > 150  # 100 Hz of messages
    assert gaps and min(gaps) >= 45, gaps  # the reading changes at most every 50 ms


def test_on_the_roof_a_disarm_waits_for_the_land_detector_a_forced_one_does_not(on_roof):
    """Take off 1.5 m over the roof, then descend onto it at 0.5 m/s as the companion does. Once
    on the roof, still asked to descend, the vehicle leans against the slope and slides, so the
    land detector (attitude error, throttle floor) has not fired: the ground station's disarm is
    refused; the forced one (21196) is not."""
    conn = on_roof
    set_interval(conn, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 20)
    set_interval(conn, M.MAVLINK_MSG_ID_DISTANCE_SENSOR, 20)
    assert set_mode(conn, 4).result == M.MAV_RESULT_ACCEPTED
    assert command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
    assert command(conn, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 1.5).result == M.MAV_RESULT_ACCEPTED
    wait_msg(conn, "EXTENDED_SYS_STATE", lambda m: m.landed_state == M.MAV_LANDED_STATE_IN_AIR)
    wait_msg(conn, "DISTANCE_SENSOR", lambda m: m.current_distance > 120)
    assert command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == M.MAV_RESULT_FAILED  # in the air
    touched = None
    for _ in range(300):  # descend, re-sent at about 10 Hz, until a second on the roof
        velocity(conn, 0.0, 0.5)
        m = conn.recv_match(type=["DISTANCE_SENSOR", "EXTENDED_SYS_STATE"], blocking=True, timeout=0.1)
        if m is not None and m.get_type() == "DISTANCE_SENSOR" and m.current_distance < 25:
            touched = touched or m.time_boot_ms
            if m.time_boot_ms - touched > 1000:
                break
    assert touched is not None, "never reached the roof"
    state = wait_msg(conn, "EXTENDED_SYS_STATE")
    velocity(conn, 0.0, 0.5)
    assert state.landed_state != M.MAV_LANDED_STATE_ON_GROUND
    assert command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == M.MAV_RESULT_FAILED
    assert command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196).result == M.MAV_RESULT_ACCEPTED
    wait_msg(conn, "HEARTBEAT", lambda m: not m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
