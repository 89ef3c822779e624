"""A plain pymavlink client sees an ArduCopter quad: mode, arming, parameters, streams."""

from __future__ import annotations

import pytest

from tests.vehicle.flying import M, arm, command, set_interval, set_mode, wait_msg

#: its tests share one vehicle (vehicle_module): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("vehicle/mavlink_basics")


def test_heartbeat_is_an_arducopter_quad(vehicle):
    _, conn = vehicle
    hb = wait_msg(conn, "HEARTBEAT")
    assert hb.type == M.MAV_TYPE_QUADROTOR
    assert hb.autopilot == M.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert hb.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.custom_mode == 0  # STABILIZE
    assert conn.mavlink20()


def test_mode_change_and_arm(vehicle):
    _, conn = vehicle
    assert set_mode(conn, 4).result == M.MAV_RESULT_ACCEPTED
    assert set_mode(conn, 99).result == M.MAV_RESULT_FAILED  # as ArduCopter: no such mode
    wait_msg(conn, "HEARTBEAT", lambda m: m.custom_mode == 4)
    assert arm(conn).result == M.MAV_RESULT_ACCEPTED
    wait_msg(conn, "HEARTBEAT", lambda m: m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
    assert command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == M.MAV_RESULT_ACCEPTED
    wait_msg(conn, "HEARTBEAT", lambda m: not m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)


def test_prearm_refuses_with_reason_and_force_overrides(vehicle):
    _, conn = vehicle
    conn.mav.rc_channels_override_send(1, 1, 0, 0, 1800, 0, 0, 0, 0, 0)  # throttle up in STABILIZE
    assert arm(conn).result == M.MAV_RESULT_FAILED
    wait_msg(conn, "STATUSTEXT", lambda m: m.text.startswith("Arm: Throttle too high"))
    conn.mav.rc_channels_override_send(1, 1, 0, 0, 1000, 0, 0, 0, 0, 0)
    command(conn, M.MAV_CMD_DO_AUX_FUNCTION, 31, 2)
    assert arm(conn).result == M.MAV_RESULT_FAILED
    wait_msg(conn, "STATUSTEXT", lambda m: "Emergency Stopped" in m.text)
    assert arm(conn, force=True).result == M.MAV_RESULT_ACCEPTED


def test_read_and_set_parameter(vehicle):
    _, conn = vehicle
    conn.mav.param_request_read_send(1, 1, b"MOT_PWM_MIN", -1)
    m = wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "MOT_PWM_MIN")
    assert m.param_value == 1525
    conn.mav.param_set_send(1, 1, b"GUID_TIMEOUT", 1.5, M.MAV_PARAM_TYPE_REAL32)
    m = wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "GUID_TIMEOUT")
    assert m.param_value == 1.5
    conn.mav.param_request_list_send(1, 1)
    first = wait_msg(conn, "PARAM_VALUE")
    assert first.param_count > 20


def test_message_interval_ceiling(vehicle):
    _, conn = vehicle
    assert set_interval(conn, M.MAVLINK_MSG_ID_HIGHRES_IMU, 200).result == M.MAV_RESULT_ACCEPTED
    assert set_interval(conn, M.MAVLINK_MSG_ID_HIGHRES_IMU, 400).result == M.MAV_RESULT_DENIED
    wait_msg(conn, "STATUSTEXT", lambda m: "too fast" in m.text)
    a = wait_msg(conn, "HIGHRES_IMU")
    b = wait_msg(conn, "HIGHRES_IMU")
    assert abs(a.zacc + 9.81) < 0.5  # level at rest: specific force up, FRD z negative
    assert 0 < b.time_usec - a.time_usec <= 10_000


def test_autopilot_version_and_timesync(vehicle):
    _, conn = vehicle
    assert command(conn, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION).result == 0
    v = wait_msg(conn, "AUTOPILOT_VERSION")
    assert v.capabilities & M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    conn.mav.timesync_send(0, 12345)
    ts = wait_msg(conn, "TIMESYNC", lambda m: m.ts1 == 12345)
    assert ts.tc1 > 0


def test_rangefinder_limits_and_system_id_use_ardupilot_names(vehicle):
    _, conn = vehicle
    conn.mav.param_request_read_send(1, 1, b"MAV_SYSID", -1)
    assert wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "MAV_SYSID").param_value == 1
    set_interval(conn, M.MAVLINK_MSG_ID_DISTANCE_SENSOR, 20)
    try:
        conn.mav.param_set_send(1, 1, b"RNGFND1_MAX", 3.0, M.MAV_PARAM_TYPE_REAL32)
        assert wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "RNGFND1_MAX").param_value == 3.0
        ds = wait_msg(conn, "DISTANCE_SENSOR", lambda m: m.max_distance == 300)  # metres -> cm
        assert ds.min_distance == 5
    finally:
        conn.mav.param_set_send(1, 1, b"RNGFND1_MAX", 14.0, M.MAV_PARAM_TYPE_REAL32)
        wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "RNGFND1_MAX")
