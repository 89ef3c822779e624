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


def range_reading(true_m: float, min_m: float, max_m: float) -> Range:
    """Status and quality of a healthy sensor for a true distance (still reported below min)."""
    if not math.isfinite(true_m) or true_m > max_m:
        return Range(max_m, 3, 0)
    if true_m < min_m:
        return Range(true_m, 2, 0)
    return Range(true_m, 4, 100)
