"""--lockstep: the vehicle does not run more than 50 ms ahead of the vehicle time a companion
echoes in TIMESYNC, runs one lead more when the companion says the same time again (it waits too),
and runs free again when the echoes stop."""

from __future__ import annotations

import time

from pymavlink import mavutil

from slopelander_sitl.vehicle.launch import start_vehicle
from tests.vehicle.conftest import ROUTE_A
from tests.vehicle.flying import M, set_interval, wait_msg


def _latest_time(conn, wall_s: float) -> float:
    t_end, last = time.monotonic() + wall_s, None
    while time.monotonic() < t_end:
        m = conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=0.05)
        if m is not None:
            last = m.time_boot_ms / 1000.0
    return last


def test_lockstep_waits_for_the_companion():
    v = start_vehicle(params=ROUTE_A, no_script=True, speed=0.0, lockstep=True, give_up_s=3.0)
    conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255)
    try:
        conn.wait_heartbeat(timeout=10)
        set_interval(conn, M.MAVLINK_MSG_ID_SYSTEM_TIME, 100)
        t_seen = wait_msg(conn, "SYSTEM_TIME").time_boot_ms / 1000.0
        # a companion that echoes t_seen and then falls silent (stuck, or busy)
        conn.mav.timesync_send(12345, int(t_seen * 1e9))
        newest = _latest_time(conn, 1.0) or t_seen
        mid = _latest_time(conn, 0.5) or newest
        # the vehicle ran on only until the echo arrived (a few ms of wall time), then waited
        assert mid == newest, (t_seen, newest, mid)
        # (before the first echo it ran free; the echo arrives within wall milliseconds, well under
        # a second of vehicle time even on a loaded machine)
        assert newest - t_seen < 1.0, (t_seen, newest)
        # the same time echoed again: "read everything, waiting" (slopelander.controller.link
        # .lockstep): what it lacks was lost, so the vehicle runs one more lead (50 ms) and waits
        conn.mav.timesync_send(12345, int(t_seen * 1e9))
        granted = _latest_time(conn, 0.5) or mid
        assert mid < granted <= mid + 0.1, (mid, granted)
        newest = granted
        # no echo for over a second: the vehicle runs free (as fast as it can, speed 0)
        t1 = _latest_time(conn, 2.5)
        assert t1 - newest > 0.5, (t_seen, newest, t1)  # far beyond the 50 ms lead it waited at
    finally:
        conn.close()
        v.stop()
