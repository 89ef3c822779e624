"""The physics server as a real process, driven by a stand-in for ArduPilot over real UDP."""

from __future__ import annotations

import functools
import math

import pytest

from slopelander.model.landing import Model
from slopelander_sitl.json_physics.ardupilot_side import ArduPilotSide
from slopelander_sitl.json_physics.launch import start_json_physics
from slopelander_sitl.vehicle.esc import command_to_pwm

QUIET = {"noise": {"accel": 0.0, "gyro": 0.0, "range": 0.0}}


@functools.cache
def hover_pwm() -> int:
    """The output at which the model's two rotors carry its weight (thrust = max * command^2)."""
    p = Model.default().params
    weight = (p["body_mass"] + 2 * p["leg_mass"]) * p["gravity"]
    return command_to_pwm(math.sqrt(weight / 2.0 / p["rotor_thrust_max"]))


def alt(s: dict) -> float:
    return -s["position"][2]


def climb(s: dict) -> float:
    return -s["velocity"][2]


def fly(ap: ArduPilotSide, seconds: float, target_alt: float, target_pitch: float = 0.0) -> dict:
    """Hold an altitude above home and a pitch (rad) with the front and rear output pairs (PD
    loops on the replies, as a crude autopilot); returns the last state."""
    s = ap.state or ap.update([1525] * 4)
    for _ in range(round(seconds * ap.frame_rate)):
        u = hover_pwm() + 150.0 * (target_alt - alt(s)) - 120.0 * climb(s)
        diff = 300.0 * (target_pitch - s["attitude"][1]) - 40.0 * s["imu.gyro"][1]  # front - rear
        front = round(min(2000.0, max(1530.0, u + diff / 2)))
        rear = round(min(2000.0, max(1530.0, u - diff / 2)))
        s = ap.update([front, rear, front, rear])
    return s


def run(ap: ArduPilotSide, seconds: float, pwm: list[int]) -> list[dict]:
    """Fixed outputs for a while; every state on the way."""
    return [dict(ap.update(pwm)) for _ in range(round(seconds * ap.frame_rate))]


@pytest.fixture(scope="module")
def pad_server():
    """One quiet server per module, vehicle on the pad; each test's new ArduPilot resets it."""
    srv = start_json_physics(scenario=QUIET)
    try:
        yield srv
    finally:
        srv.stop()


@pytest.fixture
def ap(pad_server):
    side = ArduPilotSide(pad_server.port)
    try:
        yield side
    finally:
        side.close()
