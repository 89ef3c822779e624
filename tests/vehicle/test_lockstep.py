"""--lockstep: the vehicle does not run more than 50 ms ahead of the vehicle time a companion
echoes in TIMESYNC, and runs free again when the echoes stop."""

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
    v = start_vehicle(params=ROUTE_A, no_script=True, speed=0.0, lockstep=True)
    conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255)
    try:
        conn.wait_heartbeat(timeout=10)
        set_interval(conn, M.MAVLINK_MSG_ID_SYSTEM_TIME, 100)
        t_seen = wait_msg(conn, "SYSTEM_TIME").time_boot_ms / 1000.0
        # a companion stuck at t_seen: it keeps echoing the same vehicle time
        newest, mid = t_seen, None
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2.0:
            conn.mav.timesync_send(12345, int(t_seen * 1e9))
            m = conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=0.05)
            if m is not None:
                newest = max(newest, m.time_boot_ms / 1000.0)
            if mid is None and time.monotonic() - t0 > 1.0:
                mid = newest
        # the vehicle ran on only until the first echo arrived (a few ms of wall time), then waited
        assert newest == mid, (t_seen, mid, newest)
        # (before the first echo it ran free; the echo arrives within wall milliseconds, well under
        # a second of vehicle time even on a loaded machine)
        assert newest - t_seen < 1.0, (t_seen, newest)
        # no echo for over a second: the vehicle runs free (as fast as it can, speed 0)
        t1 = _latest_time(conn, 2.5)
        assert t1 - newest > 0.5, (t_seen, newest, t1)  # far beyond the 50 ms lead it waited at
    finally:
        conn.close()
        v.stop()
