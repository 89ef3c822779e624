"""An F450's accelerometer at hover and through the cut, as the on-board script reads it
(``ins:get_accel``: the raw accelerometer through ArduPilot's INS_ACCEL_FILTER low-pass, 20 Hz).

Where each number comes from:

- **The rotors' lines.** An F450 (2212 920 KV motors, 10x4.5 in props, 3S) hovers near 5500 rpm:
  the once-per-revolution line (1P, a rotor's imbalance) near 92 Hz, the blade-pass line (2P, two
  blades) near 184 Hz; ArduPilot's FFT guide puts "a larger Copter" at "100Hz or so"
  (ardupilot.org, common-imu-fft-test-flight). The four rotors turn a few per cent apart (attitude
  and yaw trim): 88, 91, 94 and 97 Hz. A 1P imbalance rotates in the body's x-y plane and bends the
  arm (z, half of it); the 2P line is the blades' thrust ripple (z).
- **The airflow.** Broadband, 5-500 Hz, on every axis.
- **How much.** The worst vehicle ArduPilot's own two vibration checks pass: the raw accelerometer's
  vibration (VIBE: its deviation from its 5 Hz low-pass, RMS; ``AP_InertialSensor::
  calc_vibration_and_clipping``) at 30 m/s² on z and 20 on x, y, the edge of "normally acceptable"
  (ardupilot.org, common-measuring-vibration), with the airflow's share of the power set so that
  the filtered accelerometer (the IMU log's AccX/Y/Z) sits at ArduPilot's LogAnalyzer limits: two
  standard deviations of 3.0 m/s² on x, y and 5.0 on z (Tools/LogAnalyzer/tests/TestVibration.py,
  ``aimRangeFailXY``, ``aimRangeFailZ``).
- **A frame mode** (``ringing``): a lightly damped structural mode the rotors drive at hover (an
  arm's bending, the flight controller's mount), which rings down once they stop. Not part of the
  spectrum above: it is the issue-40 bench case (6-8.5 m/s² after the filter, 15-70 Hz), above
  LogAnalyzer's limits, given the physics the rotors impose on it.
- **At the cut.** The motors stop: each rotor's speed decays as exp(-t / 50 ms) (the planar
  model's rotor time constant, docs/model.md); its lines follow its speed down in frequency, their
  force its speed squared (an imbalance, a thrust ripple), and so do the airflow and the thrust.

The raw signal runs at 4 kHz (a Pixhawk's IMU samples at 1-8 kHz); ArduPilot's
``LowPassFilter2p`` (a bilinear Butterworth biquad, ``DigitalBiquadFilter::compute_params``) filters
it; the script reads the newest filtered sample each millisecond.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

G = 9.80665
RAW_HZ = 4000
FILTER_HZ = 20.0  # INS_ACCEL_FILTER
ROTOR_HZ = (88.0, 91.0, 94.0, 97.0)
ROTOR_TAU_S = 0.05
VIBE_XY, VIBE_Z = 20.0, 30.0  # m/s², raw (ArduPilot's "normally acceptable" edge on z)
LOG_2SIGMA_XY, LOG_2SIGMA_Z = 3.0, 5.0  # m/s², filtered (LogAnalyzer's fail limits)


def biquad_lowpass(x: np.ndarray, sample_hz: float, cutoff_hz: float) -> np.ndarray:
    """ArduPilot's LowPassFilter2p (DigitalBiquadFilter::compute_params, apply), started at x[0]."""
    fr = sample_hz / cutoff_hz
    ohm = math.tan(math.pi / fr)
    c = 1.0 + 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm
    b0 = ohm * ohm / c
    b1, b2 = 2.0 * b0, b0
    a1 = 2.0 * (ohm * ohm - 1.0) / c
    a2 = (1.0 - 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm) / c
    out = np.empty_like(x)
    d1 = d2 = x[0] / (1.0 + a1 + a2)  # the steady state for a constant input x[0]
    for i, xi in enumerate(x):
        d0 = xi - d1 * a1 - d2 * a2
        out[i] = d0 * b0 + d1 * b1 + d2 * b2
        d2, d1 = d1, d0
    return out


def vibe(raw: np.ndarray, sample_hz: float = RAW_HZ) -> float:
    """ArduPilot's VIBE of one axis: RMS of the raw signal less its 5 Hz low-pass (after 1 s)."""
    floor = biquad_lowpass(raw, sample_hz, 5.0)
    settle = int(sample_hz)
    return float(np.sqrt(np.mean((raw[settle:] - floor[settle:]) ** 2)))


@dataclass
class Flight:
    """A stretch of flight: ``t`` (s, 0 at the cut), the raw and filtered specific force (body FRD,
    m/s², level: z about -g) at ``RAW_HZ``."""

    t: np.ndarray
    raw: np.ndarray  # (n, 3)
    filtered: np.ndarray  # (n, 3)

    def at_ms(self, ms: int) -> tuple[float, float, float]:
        """The newest filtered sample at ``ms`` after the start (what ``ins:get_accel`` returns)."""
        i = min(len(self.t) - 1, max(0, round(ms / 1000.0 * RAW_HZ)))
        x, y, z = self.filtered[i]
        return float(x), float(y), float(z)


def _components(t: np.ndarray, cut_s: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Unit-scaled pieces of the signal: each rotor line and the airflow, with their decay."""
    after = np.clip(t - cut_s, 0.0, None)
    speed = np.exp(-after / ROTOR_TAU_S)  # fraction of hover speed; 1 before the cut
    force = speed**2
    dt = 1.0 / RAW_HZ
    pieces = {"thrust": force}
    one_p_x = np.zeros_like(t)
    one_p_y = np.zeros_like(t)
    one_p_z = np.zeros_like(t)
    two_p_z = np.zeros_like(t)
    for f in ROTOR_HZ:
        phase = 2 * math.pi * np.cumsum(f * speed) * dt + rng.uniform(0, 2 * math.pi)
        one_p_x += force * np.cos(phase)
        one_p_y += force * np.sin(phase)
        one_p_z += force * np.cos(phase + rng.uniform(0, 2 * math.pi))
        two_p_z += force * np.cos(2 * phase + rng.uniform(0, 2 * math.pi))
    pieces.update(one_p_x=one_p_x, one_p_y=one_p_y, one_p_z=0.5 * one_p_z, two_p_z=two_p_z)
    for axis in "xyz":  # airflow: white, then band-limited to 5-500 Hz
        w = rng.standard_normal(len(t))
        band = biquad_lowpass(w, RAW_HZ, 500.0) - biquad_lowpass(w, RAW_HZ, 5.0)
        pieces[f"air_{axis}"] = force * band / np.std(band)
    return pieces


def _scales(seed: int = 0) -> tuple[float, float, float, float]:
    """The amplitudes (line x-y, line z, airflow x-y, airflow z) that put a 4 s hover at VIBE
    (20 on x, y; 30 on z) with the filtered deviation at LogAnalyzer's limits, solved from a hover
    of its own (the pieces are independent, so powers add)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 4.0, 1.0 / RAW_HZ)
    p = _components(t, 1e9, rng)

    def stats(sig: np.ndarray) -> tuple[float, float]:
        raw_p = vibe(sig) ** 2
        f = biquad_lowpass(sig, RAW_HZ, FILTER_HZ)[RAW_HZ:]
        return raw_p, float(np.var(f))

    out = []
    for lines, air, vibe_target, two_sigma in (
        (p["one_p_x"], p["air_x"], VIBE_XY, LOG_2SIGMA_XY),
        (p["one_p_z"] + p["two_p_z"], p["air_z"], VIBE_Z, LOG_2SIGMA_Z),
    ):
        (r_l, f_l), (r_a, f_a) = stats(lines), stats(air)
        # a^2 r_l + b^2 r_a = vibe^2 ; a^2 f_l + b^2 f_a = (2 sigma / 2)^2
        m = np.array([[r_l, r_a], [f_l, f_a]])
        a2, b2 = np.linalg.solve(m, [vibe_target**2, (two_sigma / 2) ** 2])
        if a2 <= 0 or b2 <= 0:
            raise ValueError("these lines and airflow cannot meet both vibration limits")
        out += [math.sqrt(a2), math.sqrt(b2)]
    return out[0], out[2], out[1], out[3]


_SCALES: tuple[float, float, float, float] | None = None


def _contact(t: np.ndarray, contact: tuple[float, float, float] | None) -> np.ndarray:
    """The upward specific force (m/s²) of a contact: ``(t_s, force, rise_s)``, rising linearly
    over ``rise_s`` from ``t_s`` on and staying (a leg slipping at its friction torque)."""
    if contact is None:
        return np.zeros_like(t)
    t_c, force, rise = contact
    return force * np.clip((t - t_c) / rise, 0.0, 1.0)


def ringing(
    cut_s: float,
    length_s: float,
    amplitude: float,
    phase: float,
    mode_hz: float = 40.0,
    damping: float = 0.05,
    contact: tuple[float, float, float] | None = None,
) -> Flight:
    """A frame mode of ``mode_hz`` (damping ratio ``damping``) driven by the rotors at hover to
    ``amplitude`` m/s² on z after the filter, ringing down freely from the cut at 0 (its phase
    there ``phase``), on top of the thrust's decay; ``contact`` as in :func:`flight`."""
    t = np.arange(-cut_s, length_s - cut_s, 1.0 / RAW_HZ)
    w = 2 * math.pi * mode_hz
    gain = 1.0 / math.sqrt(1.0 + (mode_hz / FILTER_HZ) ** 4)  # the filter's, at the mode
    after = np.clip(t, 0.0, None)
    envelope = np.where(t < 0, 1.0, np.exp(-damping * w * after))
    mode = (amplitude / gain) * envelope * np.cos(w * t + phase)
    force = np.exp(-2 * after / ROTOR_TAU_S)
    z = -G * force + mode - _contact(t, contact)
    raw = np.stack([np.zeros_like(t), np.zeros_like(t), z], axis=1)
    filtered = np.stack([biquad_lowpass(raw[:, k], RAW_HZ, FILTER_HZ) for k in range(3)], axis=1)
    return Flight(t, raw, filtered)


def flight(
    cut_s: float,
    length_s: float,
    seed: int,
    cut: bool = True,
    scale: float = 1.0,
    contact: tuple[float, float, float] | None = None,
) -> Flight:
    """``length_s`` of hover (descending steadily) from ``-cut_s`` with the motors cut at 0 (never,
    with ``cut`` False); the vibration's phases and airflow drawn from ``seed``, its amplitude
    ``scale`` times the limits above; ``contact`` (t_s from the cut, upward force, rise_s) a
    contact that lifts the specific force and stays."""
    global _SCALES
    if _SCALES is None:
        _SCALES = _scales()
    line_xy, line_z, air_xy, air_z = (scale * k for k in _SCALES)
    rng = np.random.default_rng(seed)
    t = np.arange(-cut_s, length_s - cut_s, 1.0 / RAW_HZ)
    p = _components(t, 0.0 if cut else 1e9, rng)
    x = line_xy * p["one_p_x"] + air_xy * p["air_x"]
    y = line_xy * p["one_p_y"] + air_xy * p["air_y"]
    z = -G * p["thrust"] + line_z * (p["one_p_z"] + p["two_p_z"]) + air_z * p["air_z"] - _contact(t, contact)
    raw = np.stack([x, y, z], axis=1)
    filtered = np.stack([biquad_lowpass(raw[:, k], RAW_HZ, FILTER_HZ) for k in range(3)], axis=1)
    return Flight(t, raw, filtered)
