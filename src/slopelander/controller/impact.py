"""The companion's impact detector: the same rule as the on-board reflex, on streamed IMU data.

Rule: once the motors are cut, the vehicle falls freely and its accelerometer's specific force
only falls (the thrust decays) until something pushes on the vehicle. Ground contact is the first
IMU sample whose specific-force magnitude exceeds ``threshold_mps2`` (``reflex.impact_threshold_mps2``,
at least 2 g), or, from :data:`RISE_AFTER_S` (50 ms) after the cut, exceeds the lowest one since
the cut by the threshold less 1 g: once the thrust has decayed a soft first contact (an uphill leg
near the horizontal slips at a small foot force) is seen at about 1.2 g. Before the 50 ms the
rotors' vibration is still there, and a trough followed by a crest read as a rise in the air
(issue 40; tests/controller/test_impact_vibration.py), as in the script, which counts the rise
from the same moment. And the sample must push up the body (its FRD z below
``-IMPACT_UP_MPS2``): the roof pushes on the feet within its friction cone and the legs carry it to
the body from below, so a reading pointing down the body is no contact (an accelerometer spike in
the fall fired reverse thrust 0.12 s above a 50 deg roof in the soak). Samples count only after
the cut and only when newer than the previous one (a repeated or reordered packet never counts
twice).

Latency budget from contact to the companion's decision (RAW_IMU at 200 Hz):
  autopilot 20 Hz low-pass filter (two-pole, INS_ACCEL_FILTER)                  ~ 8-10 ms to rise
  sample interval of the stream (1/200 Hz)                                     <= 5 ms
  serial/UDP transit                                                           ~ 1-3 ms
  the companion's loop period (``link.poll_period_s``, 10 ms; every sample
  received in between is still fed, in order)                                  <= 10 ms
  decision (one comparison)                                                    < 0.1 ms
so about 15-25 ms, against about 2-3 ms for the on-board script that runs the same rule at the
loop rate with no link in between. That is why the reflex lives on board; the companion's detector
is the backstop and the record, and what it measures is reported by benchmarks/landing_latency.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from slopelander.controller.script_contract import IMPACT_UP_MPS2, RISE_AFTER_S

G = 9.80665


@dataclass(frozen=True)
class Impact:
    """The sample that tripped the detector: vehicle time (s) and its magnitude (m/s²)."""

    t: float
    accel_mps2: float


def raw_imu_accel(msg) -> tuple[float, float, float]:
    """RAW_IMU accelerations (milli-g) in m/s²."""
    return (msg.xacc * G / 1000.0, msg.yacc * G / 1000.0, msg.zacc * G / 1000.0)


class ImpactDetector:
    """Feed IMU samples; after :meth:`arm_after_cut`, :attr:`impact` is set by the first large one."""

    def __init__(self, threshold_mps2: float) -> None:
        if not (math.isfinite(threshold_mps2) and threshold_mps2 > G):
            raise ValueError(
                f"impact threshold must be a number of m/s² above 1 g ({G} m/s²: it counts above the "
                f"thrust's share), got {threshold_mps2!r}"
            )
        self.threshold = threshold_mps2
        self.cut_at: float | None = None
        self.impact: Impact | None = None
        self.floor: float | None = None  # the lowest magnitude since the cut
        self._last_t = -math.inf

    def arm_after_cut(self, t_cut: float) -> None:
        """Watch samples later than vehicle time ``t_cut`` (s)."""
        self.cut_at = t_cut
        self.impact = None
        self.floor = None

    def reset(self) -> None:
        """Stop watching."""
        self.cut_at = None
        self.impact = None
        self.floor = None

    def feed(self, t: float, ax: float, ay: float, az: float) -> Impact | None:
        """One sample at vehicle time ``t`` (s), m/s²; returns the impact when this sample is it."""
        if t <= self._last_t:
            return None
        self._last_t = t
        if self.cut_at is None or self.impact is not None or t <= self.cut_at:
            return None
        a = math.sqrt(ax * ax + ay * ay + az * az)
        if not math.isfinite(a):
            return None  # a corrupt sample is not an impact; the range and the script still watch
        self.floor = a if self.floor is None else min(self.floor, a)
        threshold = self.threshold
        if t - self.cut_at >= RISE_AFTER_S:
            threshold = min(threshold, self.floor + self.threshold - G)
        if a > threshold and -az > IMPACT_UP_MPS2:
            self.impact = Impact(t, a)
            return self.impact
        return None

    def feed_msg(self, msg) -> Impact | None:
        """A RAW_IMU (milli-g) or HIGHRES_IMU (m/s²) message."""
        kind = msg.get_type()
        if kind == "RAW_IMU":
            return self.feed(msg.time_usec / 1e6, *raw_imu_accel(msg))
        if kind == "HIGHRES_IMU":
            return self.feed(msg.time_usec / 1e6, msg.xacc, msg.yacc, msg.zacc)
        return None
