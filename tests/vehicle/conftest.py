"""Fixtures that start the simulated vehicle as a real process on a free port."""

from __future__ import annotations

import os

os.environ.setdefault("MAVLINK20", "1")

import pytest
from pymavlink import mavutil

from slopelander_sitl.vehicle.launch import start_vehicle

ROUTE_A = {"FRAME_CLASS": 1, "MOT_PWM_TYPE": 0, "MOT_PWM_MIN": 1525, "MOT_PWM_MAX": 2000}


@pytest.fixture(scope="module")
def vehicle_module():
    """One vehicle per test module (starting one compiles the model: about 15 s)."""
    v = start_vehicle(params=ROUTE_A, no_script=True, speed=2.0)
    conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255, source_component=190)
    try:
        assert conn.wait_heartbeat(timeout=10) is not None
        yield v, conn
    finally:
        conn.close()
        v.stop()


@pytest.fixture
def vehicle(vehicle_module):
    """The module's vehicle, disarmed in STABILIZE with no stop and no RC override."""
    from tests.vehicle.flying import reset

    reset(vehicle_module[1])
    return vehicle_module
