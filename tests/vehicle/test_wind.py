"""Wind from the scenario reaches the physics: a hovering vehicle in GUIDED is pushed off its
position by a gust and the position controller brings it back; a bad wind section stops the
vehicle from starting with a message naming the field."""

from __future__ import annotations

import numpy as np
import pytest
from pymavlink import mavutil

from slopelander_sitl.vehicle.launch import start_vehicle
from tests.vehicle.conftest import ROUTE_A
from tests.vehicle.flying import HOME_OVER_PAD_M, take_off, wait_msg

GUST_T, GUST_S, GUST_N = 20.0, 2.0, 4.0


def test_a_gust_pushes_the_hovering_vehicle_and_it_comes_back():
    scenario = {"wind": {"gusts": [{"t_s": GUST_T, "duration_s": GUST_S, "fx_n": GUST_N, "fz_n": 0}]}}
    v = start_vehicle(params=ROUTE_A, no_script=True, speed=4.0, scenario=scenario)
    conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255)
    try:
        conn.wait_heartbeat(timeout=10)
        take_off(conn, 1.5)
        first = wait_msg(conn, "LOCAL_POSITION_NED", lambda m: m.z < -1.25, timeout=15)
        assert first.time_boot_ms < (GUST_T - 2.0) * 1000, "took too long to reach the hover"
        rows = []
        while not rows or rows[-1][0] < GUST_T + GUST_S + 12.0:
            m = wait_msg(conn, "LOCAL_POSITION_NED")
            rows.append((m.time_boot_ms / 1000.0, m.x, m.z))
    finally:
        conn.close()
        v.stop()
    r = np.array(rows)
    before = r[(r[:, 0] > GUST_T - 2.0) & (r[:, 0] < GUST_T)]
    since = r[r[:, 0] >= GUST_T]
    after = r[r[:, 0] > GUST_T + GUST_S + 10.0]
    x0 = before[:, 1].mean()
    assert np.abs(before[:, 1] - x0).max() < 0.03  # still air: holds its position
    drift = since[:, 1] - x0
    # 4 N on 1.56 kg is more than the horizontal integrator can hold: pushed toward +x (north),
    # the gust's direction, then back past its position (the integrator unwinds) and slowly home
    assert drift.max() > 0.3, drift.max()
    assert np.argmax(drift) < np.argmin(drift)
    assert np.abs(after[:, 1] - x0).max() < 0.05, after[:, 1] - x0  # back where it was
    assert np.abs(after[:, 2] + 1.5 - HOME_OVER_PAD_M).max() < 0.1  # and at its height over the pad


def test_a_bad_wind_section_is_refused_naming_the_field():
    with pytest.raises(RuntimeError, match=r"wind\.gusts\[0\]\.fx_n"):
        start_vehicle(
            params=ROUTE_A,
            no_script=True,
            scenario={"wind": {"gusts": [{"t_s": 1, "duration_s": 1, "fx_n": "gale"}]}},
            timeout=30,
        )
