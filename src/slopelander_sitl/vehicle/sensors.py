"""IMU and downward rangefinder as ArduPilot sees them, read from the model's Stepper.

The IMU low-passes specific force and rate at INS_ACCEL_FILTER / INS_GYRO_FILTER after adding
noise, as ArduPilot's filtered ``ins:get_accel`` does: a two-pole Butterworth low-pass at the
sample rate (AP_InertialSensor.h: ``LowPassFilter2pVector3f _accel_filter``, "2-pole low-pass
filter for accel (INS_ACCEL_FILTER)"; the biquad of libraries/Filter/LowPassFilter2p.cpp),
started at the first sample. A first-order filter let a short impact through that ArduCopter's
filter holds under the 2 g threshold. The rangefinder reads along the body down axis; faults from
the scenario act on the reading.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Range:
    distance_m: float
    status: int  # ArduPilot RangeFinder::Status: 1 NoData, 2 OutOfRangeLow, 3 OutOfRangeHigh, 4 Good
    quality_pct: int  # -1 unknown, 0 invalid .. 100


class NormalStream:
    """A Generator's standard normal draws, drawn in blocks and handed out in order.

    numpy's Generator draws each value of ``normal(size=n)`` exactly as n calls of ``normal()``
    would (no cached pairs, the same ziggurat per value), so whatever mix of ``take(6)`` and
    ``normal()`` its users make, they get the same numbers in the same order as from the
    Generator itself; only the Generator's own state runs ahead, so every user of it must draw
    through this stream. A draw from numpy costs about a microsecond whatever its size, and the
    simulators draw seven values 1,200 times a simulated second.
    """

    BLOCK = 6 * 256

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self._buf: list[float] = []
        self._i = 0

    def take(self, n: int) -> list[float]:
        """The next ``n`` draws."""
        i, j = self._i, self._i + n
        if j > len(self._buf):
            self._refill(n)
            i, j = 0, n
        self._i = j
        return self._buf[i:j]

    def normal(self) -> float:
        """The next draw: ``Generator.normal()``'s value."""
        i = self._i
        if i >= len(self._buf):
            self._refill(1)
            i = 0
        self._i = i + 1
        return self._buf[i]

    def _refill(self, n: int) -> None:
        rest = self._buf[self._i :]
        self._buf = rest + self.rng.normal(size=max(self.BLOCK, n)).tolist()
        self._i = 0


class Imu:
    """Filtered specific force (body FRD, m/s^2) and rates (rad/s). Given a
    :class:`NormalStream`, its noise comes from there (whoever else draws from the same
    Generator must draw through that stream too); given a Generator, one draw per sample."""

    def __init__(
        self, rng: np.random.Generator | NormalStream, accel_noise: float, gyro_noise: float
    ) -> None:
        self.rng = rng
        self._stream = rng if isinstance(rng, NormalStream) else None
        self.accel_noise = accel_noise
        self.gyro_noise = gyro_noise
        self.accel: tuple[float, ...] = (0.0, 0.0, -9.81)
        self.gyro: tuple[float, ...] = (0.0, 0.0, 0.0)
        self.raw_accel, self.raw_gyro = self.accel, self.gyro
        self._accel_lp = LowPass2p()
        self._gyro_lp = LowPass2p()

    def update(
        self,
        dt: float,
        fx: float,
        fz_up: float,
        pitch_rate: float,
        cut_a_hz: float,
        cut_g_hz: float,
        spike: float = 0.0,
        roll_rate: float = 0.0,
        yaw_rate: float = 0.0,
    ) -> None:
        """One sample: the planar body's forward and up specific force and pitch rate, and the
        turn's body rates (a heading turning at r with the nose pitched by theta: roll rate
        -r sin(theta), yaw rate r cos(theta)); noise added, then the filters."""
        # plain floats, in the order numpy's vector arithmetic took (the same numbers): 1,200
        # times a simulated second, small arrays cost more than the arithmetic
        stream = self._stream
        n0, n1, n2, n3, n4, n5 = stream.take(6) if stream is not None else self.rng.normal(size=6).tolist()
        sa, sg = self.accel_noise, self.gyro_noise
        a = (fx + sa * n0, 0.0 + sa * n1, (-fz_up + sa * n2) + spike)
        g = (roll_rate + sg * n3, pitch_rate + sg * n4, yaw_rate + sg * n5)
        self.raw_accel, self.raw_gyro = a, g
        self.accel = self._accel_lp.apply(a, dt, cut_a_hz)
        self.gyro = self._gyro_lp.apply(g, dt, cut_g_hz)


class LowPass2p:
    """Two-pole Butterworth low-pass (a biquad, direct form II), ArduPilot's ``LowPassFilter2p``:
    coefficients from the sample rate and the cutoff (the bilinear transform: scipy's
    ``butter(2, ...)``); a cutoff of 0, or at or above half the sample rate, passes the sample
    through. The delay elements start at the first sample's steady state, so the filter does not
    ring up from zero."""

    def __init__(self) -> None:
        self._d1: list[float] | None = None
        self._d2: list[float] | None = None
        self._key: tuple[float, float] | None = None
        self._coef = (1.0, 2.0, 1.0, 0.0, 0.0)
        self._dt = self._cutoff = math.nan  # _key's two parts, compared without a tuple

    def _coefficients(self, dt: float, cutoff_hz: float) -> tuple[float, float, float, float, float]:
        if self._key != (dt, cutoff_hz):
            ohm = math.tan(math.pi * cutoff_hz * dt)
            c = 1.0 + 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm
            b0 = ohm * ohm / c
            a1 = 2.0 * (ohm * ohm - 1.0) / c
            a2 = (1.0 - 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm) / c
            self._key, self._coef = (dt, cutoff_hz), (b0, 2.0 * b0, b0, a1, a2)
            self._dt, self._cutoff = dt, cutoff_hz
        return self._coef

    def apply(self, x: Sequence[float], dt: float, cutoff_hz: float) -> tuple[float, ...]:
        """One sample of each axis in, the filtered sample of each out (plain floats: a vector of
        three costs more as a numpy array than its arithmetic)."""
        if cutoff_hz <= 0.0 or dt <= 0.0 or cutoff_hz * dt >= 0.5:
            return tuple(map(float, x))
        if dt == self._dt and cutoff_hz == self._cutoff:  # _coefficients' own test, inline
            b0, b1, b2, a1, a2 = self._coef
        else:
            b0, b1, b2, a1, a2 = self._coefficients(dt, cutoff_hz)
        if self._d1 is None or self._d2 is None:
            g = b0 + b1 + b2
            self._d1 = self._d2 = [float(v) / g for v in x]
        d1, d2 = self._d1, self._d2
        if len(x) == 3 and len(d1) == 3:
            # the general loop below written out for the IMU's three axes (1,200 times a
            # simulated second, twice): the same operations in the same order
            x0, x1, x2 = x
            p0, p1, p2 = d1
            q0, q1, q2 = d2
            z0 = float(x0) - p0 * a1 - q0 * a2
            z1 = float(x1) - p1 * a1 - q1 * a2
            z2 = float(x2) - p2 * a1 - q2 * a2
            self._d2, self._d1 = d1, [z0, z1, z2]
            return (z0 * b0 + p0 * b1 + q0 * b2, z1 * b0 + p1 * b1 + q1 * b2, z2 * b0 + p2 * b1 + q2 * b2)
        d0 = [float(v) - p * a1 - q * a2 for v, p, q in zip(x, d1, d2, strict=True)]
        out = tuple(z * b0 + p * b1 + q * b2 for z, p, q in zip(d0, d1, d2, strict=True))
        self._d2, self._d1 = d1, d0
        return out


BEAM_MISS_M = 999.0  # what the beam reads when it meets no surface (the JSON physics sends the same)


def range_reading(value_m: float, min_m: float, max_m: float) -> Range:
    """The reading ArduPilot makes of a rangefinder value (arducopter_rules.sitl_rangefinder):
    NaN/inf no data, negative 0 m, below RNGFND1_MIN still reported (out of range low), above
    RNGFND1_MAX out of range high (reported as RNGFND1_MAX)."""
    from slopelander_sitl.vehicle.arducopter_rules import GOOD, NO_DATA, OUT_OF_RANGE_HIGH, sitl_rangefinder

    d, status = sitl_rangefinder(value_m, min_m, max_m)
    if status == NO_DATA:
        return Range(0.0, NO_DATA, 0)
    if status == OUT_OF_RANGE_HIGH:
        return Range(max_m, status, 0)
    return Range(d, status, 100 if status == GOOD else 0)
