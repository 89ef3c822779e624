"""Small pymavlink helpers the vehicle tests share (plain client calls, no test logic)."""

from __future__ import annotations

import time

from pymavlink import mavutil

M = mavutil.mavlink


def _seen(conn) -> list:
    """Messages that arrived while waiting for an ACK, kept for the next wait_msg."""
    if not hasattr(conn, "_sl_seen"):
        conn._sl_seen = []
    return conn._sl_seen


def command(conn, cmd: int, *params: float, timeout: float = 5.0):
    p = list(params) + [0.0] * (7 - len(params))
    conn.mav.command_long_send(1, 1, cmd, 0, *p)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        m = conn.recv_match(blocking=True, timeout=0.2)
        if m is None:
            continue
        if m.get_type() == "COMMAND_ACK" and m.command == cmd:
            return m
        _seen(conn).append(m)
    raise AssertionError(f"no COMMAND_ACK for {cmd}")


def set_mode(conn, mode: int):
    return command(conn, M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode)


FORCE_ARM = 2989  # ArduPilot's force-arm magic (21196 forces a disarm only)


def arm(conn, force: bool = False):
    return command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 1, FORCE_ARM if force else 0)


def wait_msg(conn, kind: str, cond=lambda m: True, timeout: float = 10.0):
    seen = _seen(conn)
    for i, m in enumerate(seen):
        if m.get_type() == kind and cond(m):
            del seen[: i + 1]
            return m
    seen.clear()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        m = conn.recv_match(type=kind, blocking=True, timeout=0.2)
        if m is not None and cond(m):
            return m
    raise AssertionError(f"no {kind} matching within {timeout} s")


def set_interval(conn, msgid: int, hz: float):
    return command(conn, M.MAV_CMD_SET_MESSAGE_INTERVAL, msgid, 1e6 / hz)


def velocity(conn, vx: float, vz_down: float) -> None:
    conn.mav.set_position_target_local_ned_send(
        0, 1, 1, M.MAV_FRAME_LOCAL_NED, 0x0DC7, 0, 0, 0, vx, 0, vz_down, 0, 0, 0, 0, 0
    )


HOME_OVER_PAD_M = 0.148  # home is the body's origin as it first settled on the pad


def take_off(conn, alt: float) -> None:
    """GUIDED, arm, MAV_CMD_NAV_TAKEOFF to ``alt``: metres over the surface the rangefinder sees
    when it is healthy and ``alt`` is below RNGFND1_MAX (ArduCopter's rule), else above home.
    It waits for 1 s of vehicle time first: before RANGEFINDER_HEALTH_MAX readings (20 Hz) the
    rangefinder is not yet healthy and the height would be over home, a race a loaded machine loses."""
    wait_msg(conn, "ATTITUDE", lambda m: m.time_boot_ms >= 1000, timeout=30)
    assert set_mode(conn, 4).result == M.MAV_RESULT_ACCEPTED
    assert arm(conn).result == M.MAV_RESULT_ACCEPTED
    assert command(conn, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, alt).result == M.MAV_RESULT_ACCEPTED


def reset(conn) -> None:
    """Disarm (forced), emergency stop off, STABILIZE, RC overrides released, defaults back."""
    command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196)
    command(conn, M.MAV_CMD_DO_AUX_FUNCTION, 31, 0)
    set_mode(conn, 0)
    conn.mav.rc_channels_override_send(1, 1, 0, 0, 0, 0, 0, 0, 0, 0)
    for name, value in (("ANGLE_MAX", 3000.0), ("GUID_TIMEOUT", 3.0)):
        conn.mav.param_set_send(1, 1, name.encode(), value, M.MAV_PARAM_TYPE_REAL32)
        wait_msg(conn, "PARAM_VALUE", lambda m, n=name: m.param_id == n)
    _seen(conn).clear()
