"""IMU and downward rangefinder as ArduPilot sees them, read from the model's Stepper.

The IMU low-passes specific force and rate at INS_ACCEL_FILTER / INS_GYRO_FILTER (first order,
at the physics rate) after adding noise, as ArduPilot's filtered ``ins:get_accel`` does. The
rangefinder reads along the body down axis; faults from the scenario act on the reading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Range:
    distance_m: float
    status: int  # ArduPilot RangeFinder::Status: 1 NoData, 2 OutOfRangeLow, 3 OutOfRangeHigh, 4 Good
    quality_pct: int  # -1 unknown, 0 invalid .. 100


class Imu:
    """Filtered specific force (body FRD, m/s^2) and rates (rad/s)."""

    def __init__(self, rng: np.random.Generator, accel_noise: float, gyro_noise: float) -> None:
        self.rng = rng
        self.accel_noise = accel_noise
        self.gyro_noise = gyro_noise
        self.accel = np.array([0.0, 0.0, -9.81])
        self.gyro = np.zeros(3)
        self.raw_accel = self.accel.copy()
        self.raw_gyro = self.gyro.copy()

    def update(
        self,
        dt: float,
        fx: float,
        fz_up: float,
        pitch_rate: float,
        cut_a_hz: float,
        cut_g_hz: float,
        spike: float = 0.0,
    ) -> None:
        n = self.rng.normal(size=6)
        a = np.array([fx, 0.0, -fz_up]) + self.accel_noise * n[:3]
        a[2] += spike
        g = np.array([0.0, pitch_rate, 0.0]) + self.gyro_noise * n[3:]
        self.raw_accel, self.raw_gyro = a, g
        self.accel += _alpha(dt, cut_a_hz) * (a - self.accel)
        self.gyro += _alpha(dt, cut_g_hz) * (g - self.gyro)


def _alpha(dt: float, cutoff_hz: float) -> float:
    if cutoff_hz <= 0:
        return 1.0
    rc = 1.0 / (2.0 * math.pi * cutoff_hz)
    return dt / (dt + rc)


BEAM_MISS_M = 999.0  # what the beam reads when it meets no surface (the JSON physics sends the same)


def range_reading(value_m: float, min_m: float, max_m: float) -> Range:
    """The reading ArduPilot makes of a rangefinder value (arducopter_rules.sitl_rangefinder):
    NaN/inf no data, negative 0 m, below RNGFND1_MIN still reported (out of range low), above
    RNGFND1_MAX out of range high (reported as RNGFND1_MAX)."""
    from sitl.vehicle.arducopter_rules import GOOD, NO_DATA, OUT_OF_RANGE_HIGH, sitl_rangefinder

    d, status = sitl_rangefinder(value_m, min_m, max_m)
    if status == NO_DATA:
        return Range(0.0, NO_DATA, 0)
    if status == OUT_OF_RANGE_HIGH:
        return Range(max_m, status, 0)
    return Range(d, status, 100 if status == GOOD else 0)
