"""The model seen as the autopilot sees a landing: its body's specific force and pitch rate
through the autopilot's own IMU filters, sampled where the log sampled.

ArduPilot low-passes each accelerometer and gyro sample with a 2-pole filter
(``LowPassFilter2p``: a Butterworth biquad by the bilinear transform with prewarping, the
design ``scipy.signal.butter(2, cutoff, fs=rate)`` makes) at ``INS_ACCEL_FILTER`` /
``INS_GYRO_FILTER`` Hz, and logs the filtered values. The model's signals get the same filter at
the IMU's sample rate, started where the log's filtered values stood at contact: the model
begins at contact and has no history for the filter to remember (the thrust of the descent, or
the free fall after the cut).

The still rule is the on-board script's for its disarm (docs/onboard-script.md): body rates
below 5 deg/s and speed below 0.10 m/s, here held for :data:`REST_HOLD_S`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from slopelander.model import LandingConditions, Model, Outcome, simulate
from slopelander.model import kernel as k

STILL_RATE_DPS = 5.0
STILL_SPEED_MPS = 0.10
REST_HOLD_S = 0.5
"""s the still rule must hold for the vehicle to be at rest."""
IMPACT_S = 0.5
"""s after contact in which the largest acceleration is the impact's."""
FIRST_PEAK_S = 0.1
"""s after contact in which the first contact's own peak is looked for."""
FIRST_PEAK_RISE = 1.0
"""m/s^2 the first contact's peak rises at least above the reading at contact."""


def lowpass(x: np.ndarray, cutoff_hz: float, sample_hz: float, start: float) -> np.ndarray:
    """``x`` (evenly sampled at ``sample_hz``) through ArduPilot's 2-pole low-pass at
    ``cutoff_hz``, its state settled on the value ``start`` before the first sample."""
    from scipy.signal import butter, lfilter, lfilter_zi

    if cutoff_hz <= 0 or cutoff_hz >= sample_hz / 2:
        return x.copy()  # ArduPilot passes the signal through unfiltered then
    b, a = butter(2, cutoff_hz, fs=sample_hz)
    y, _ = lfilter(b, a, x, zi=lfilter_zi(b, a) * start)
    return y


@dataclass(frozen=True)
class ModelView:
    """The model's landing at the log's conditions, as the log's sensors would show it (time in
    s from first contact)."""

    t: np.ndarray
    pitch_deg: np.ndarray
    pitch_rate_dps: np.ndarray
    """filtered as the gyro is"""
    accel: np.ndarray
    """(n, 2): specific force forward and down (m/s^2), filtered as the accelerometer is"""
    speed: np.ndarray
    """m/s, the body's speed"""
    x: np.ndarray
    """m, the body's horizontal position downhill"""
    outcome: Outcome
    sample_hz: float


def observe(
    model: Model,
    cond: LandingConditions,
    duration: float,
    filters: dict,
    accel_at_contact: tuple[float, float],
) -> ModelView:
    """Simulate ``cond`` for ``duration`` s after contact and observe it through ``filters``
    (:attr:`FlightLog.filters`), the accelerometer's filter started at ``accel_at_contact``
    (forward, down; m/s^2)."""
    fs = float(filters["sample_hz"])
    m = replace(model, criteria=replace(model.criteria, horizon=max(duration, model.criteria.horizon)))
    tr = simulate(cond, m, sample_rate=fs, full_horizon=True)
    t, raw = tr.t, tr.raw
    fs = 1.0 / float(np.median(np.diff(t)))  # the rate simulate could sample at (its steps)
    vx, vz = raw[:, k.S_V], raw[:, k.S_V + 1]
    pitch, rate = raw[:, k.S_Q + 2], raw[:, k.S_V + 2]
    g = model.params["gravity"]
    ax, az = np.gradient(vx, t), np.gradient(vz, t) + g
    c, s = np.cos(pitch), np.sin(pitch)
    forward, up = c * ax + s * az, -s * ax + c * az
    acc = np.column_stack(
        [
            lowpass(forward, float(filters["accel_hz"]), fs, accel_at_contact[0]),
            lowpass(-up, float(filters["accel_hz"]), fs, accel_at_contact[1]),
        ]
    )
    gyro = lowpass(np.degrees(rate), float(filters["gyro_hz"]), fs, math.degrees(float(rate[0])))
    return ModelView(
        t=t,
        pitch_deg=np.degrees(pitch),
        pitch_rate_dps=gyro,
        accel=acc,
        speed=np.hypot(vx, vz),
        x=raw[:, k.S_Q],
        outcome=tr.result.outcome,
        sample_hz=fs,
    )


def rest_time(t: np.ndarray, rate_dps: np.ndarray, speed: np.ndarray) -> float | None:
    """The first time from which the body stays still (:data:`STILL_RATE_DPS`,
    :data:`STILL_SPEED_MPS`) for :data:`REST_HOLD_S`, or None within ``t``."""
    still = (np.abs(rate_dps) < STILL_RATE_DPS) & (speed < STILL_SPEED_MPS)
    if not len(t):
        return None
    # the end of each run of still samples
    moving_after = np.full(len(t), np.inf)
    nxt = np.inf
    for i in range(len(t) - 1, -1, -1):
        if not still[i]:
            nxt = t[i]
        moving_after[i] = nxt
    for i in np.nonzero(still)[0]:
        if i > 0 and still[i - 1]:
            continue  # only the start of a run
        end = moving_after[i]
        if (end if math.isfinite(end) else t[-1]) - t[i] >= REST_HOLD_S:
            return float(t[i])
    return None


def impact_peak(t: np.ndarray, magnitude: np.ndarray) -> tuple[float, float] | None:
    """(time, size) of the largest magnitude within :data:`IMPACT_S` after contact."""
    m = (t >= 0) & (t <= IMPACT_S)
    if not m.any():
        return None
    i = int(np.argmax(np.where(m, magnitude, -np.inf)))
    return float(t[i]), float(magnitude[i])


def first_peak(t: np.ndarray, magnitude: np.ndarray) -> tuple[float, float] | None:
    """(time, size) of the first contact's own peak: the first local maximum within
    :data:`FIRST_PEAK_S` after contact that stands :data:`FIRST_PEAK_RISE` above the reading at
    contact (on a steep roof one foot lands first, and the largest peak is often the others')."""
    idx = np.nonzero((t >= 0) & (t <= FIRST_PEAK_S))[0]
    if len(idx) < 3:
        return None
    base = float(magnitude[idx[0]])
    for i in idx[1:-1]:
        a = magnitude[i]
        if a - base >= FIRST_PEAK_RISE and a >= magnitude[i - 1] and a > magnitude[i + 1]:
            return float(t[i]), float(a)
    return None
