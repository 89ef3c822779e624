"""GUIDED flight over MAVLink: take-off and hover hold altitude, a 0.5 m/s descent is held,
a stale velocity target stops the descent (GUID_TIMEOUT)."""

from __future__ import annotations

import time

import numpy as np

from tests.vehicle.flying import HOME_OVER_PAD_M, M, take_off, velocity, wait_msg


def _positions(conn, seconds_vehicle: float) -> np.ndarray:
    """(t_s, z_down_m, vz_down) rows from LOCAL_POSITION_NED over a span of vehicle time."""
    rows = []
    first = wait_msg(conn, "LOCAL_POSITION_NED")
    while True:
        m = wait_msg(conn, "LOCAL_POSITION_NED")
        rows.append((m.time_boot_ms / 1000.0, m.z, m.vz))
        if (m.time_boot_ms - first.time_boot_ms) / 1000.0 >= seconds_vehicle:
            return np.array(rows)


def test_take_off_hover_descend_and_stale_target(vehicle):
    _, conn = vehicle
    conn.mav.param_set_send(1, 1, b"GUID_TIMEOUT", 1.0, M.MAV_PARAM_TYPE_REAL32)
    wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == "GUID_TIMEOUT")
    take_off(conn, 2.5)
    wait_msg(conn, "LOCAL_POSITION_NED", lambda m: m.z < -2.25, timeout=10)
    wait_msg(conn, "EXTENDED_SYS_STATE", lambda m: m.landed_state == M.MAV_LANDED_STATE_IN_AIR)
    time.sleep(1.0)
    hover = _positions(conn, 2.0)
    # 2.5 m over the pad the rangefinder sees (a GUIDED take-off below RNGFND1_MAX is over the
    # terrain), home being the body's origin as it sat on the pad
    assert abs(hover[:, 1].mean() + 2.5 - HOME_OVER_PAD_M) < 0.1, hover[:, 1].mean()
    assert hover[:, 1].std() < 0.05

    # descend at 0.5 m/s for 2 s of vehicle time (a loaded machine slows the vehicle, not its
    # clock): a target re-sent at 10 Hz wall. The socket is drained after each send, so t_sent
    # is the vehicle's time now, not a stale message still queued (the vehicle streams faster
    # than one message per send). The rate is judged over the second vehicle second.
    rows = []
    t_sent = t_first = None
    wall_end = time.monotonic() + 20.0
    while time.monotonic() < wall_end and (t_first is None or t_sent - t_first < 2.0):
        velocity(conn, 0.0, 0.5)
        t_next = time.monotonic() + 0.1
        while time.monotonic() < t_next:
            m = conn.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=0.02)
            if m is not None:
                t_sent = m.time_boot_ms / 1000.0  # vehicle time at (or just after) the last target
                t_first = t_sent if t_first is None else t_first
                rows.append((t_sent, m.vz))
    assert t_sent is not None and t_sent - t_first >= 2.0, (t_first, t_sent)
    late = np.array([vz for t, vz in rows if t >= t_first + 1.0])
    assert abs(late.mean() - 0.5) < 0.08, late.mean()

    # stop sending: after GUID_TIMEOUT (1 s) the vehicle stops descending and holds
    held = _positions(conn, 3.5)
    held = held[held[:, 0] > t_sent + 1.0 + 1.0]
    assert len(held) > 5
    assert abs(held[:, 2]).max() < 0.15, held[:, 2]
    assert held[:, 1].max() - held[:, 1].min() < 0.1
    assert held[:, 1].mean() < -0.5  # still in the air
