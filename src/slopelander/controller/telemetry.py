"""What a landing's telemetry shows: the recorder a session listens with, and the figures read from it.

:class:`Telemetry` keeps the time series the flight picture is drawn from (vehicle time, SI units):
height, speed, range, acceleration, pitch, the motors' outputs and the leg board's reports. The
figures a pilot reads after a landing (impact speed at the first contact, the slide, the lowest
pitch, the uphill legs' angle before the cut) are computed from it, as the on-board script's own
rules would see them. Pure Python: it runs on the companion with the core install.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

G_MPS2 = 9.80665
#: a foot on the roof while the motors still hold the vehicle (the powered descent reads 1 g, and
#: after the cut the reading only falls): a reading this far above 1 g. The cut latency and the
#: rotors' spin-down let the uphill foot of a steep roof touch under thrust, at 1.6-1.9 g: under
#: the script's 2 g with the thrust's g in it, so the script reverses at the harder contact after
POWERED_TOUCH_MPS2 = 0.3 * G_MPS2
#: a contact began where the reading rose this far above 1 g (the descent's corrections stay under)
ONSET_MPS2 = 0.02 * G_MPS2
#: the accelerometer's low-pass (ArduPilot's two-pole Butterworth at INS_ACCEL_FILTER, 20 Hz) delays
#: a reading by sqrt(2) / (2 pi 20 Hz) = 11 ms: the velocity report before a contact is looked for
#: that much before the reading's rise
FILTER_DELAY_S = math.sqrt(2.0) / (2.0 * math.pi * 20.0)


@dataclass
class Telemetry:
    """Time series the picture is drawn from (vehicle time, SI units)."""

    t: list[float] = field(default_factory=list)
    height: list[float] = field(default_factory=list)  # above the pad, from LOCAL_POSITION_NED
    vz_up: list[float] = field(default_factory=list)
    range_t: list[float] = field(default_factory=list)
    range_m: list[float] = field(default_factory=list)
    accel_t: list[float] = field(default_factory=list)
    accel: list[float] = field(default_factory=list)
    pitch_t: list[float] = field(default_factory=list)
    pitch_deg: list[float] = field(default_factory=list)
    servo_t: list[float] = field(default_factory=list)
    servo: list[list[int]] = field(default_factory=list)
    legs_t: list[float] = field(default_factory=list)
    leg_torque: list[list[float]] = field(default_factory=list)
    leg_angle: list[list[float]] = field(default_factory=list)
    x_t: list[float] = field(default_factory=list)
    x: list[float] = field(default_factory=list)
    legs: object = None  # the leg-board driver whose reports are sampled with the position

    def listen(self, msg: object) -> None:
        kind = msg.get_type()  # type: ignore[attr-defined]
        if kind == "LOCAL_POSITION_NED":
            t = msg.time_boot_ms / 1000.0  # type: ignore[attr-defined]
            status = getattr(self.legs, "status", None)
            if status is not None:
                self.legs_t.append(t)
                self.leg_torque.append(
                    [math.nan if s.torque_nm is None else s.torque_nm for s in status.legs]
                )
                self.leg_angle.append([s.angle_deg for s in status.legs])
            self.t.append(t)
            self.height.append(-msg.z)  # type: ignore[attr-defined]
            self.vz_up.append(-msg.vz)  # type: ignore[attr-defined]
            self.x_t.append(t)
            self.x.append(msg.x)  # type: ignore[attr-defined]
        elif kind == "DISTANCE_SENSOR":
            self.range_t.append(msg.time_boot_ms / 1000.0)  # type: ignore[attr-defined]
            self.range_m.append(msg.current_distance / 100.0)  # type: ignore[attr-defined]
        elif kind == "RAW_IMU":
            a = (msg.xacc, msg.yacc, msg.zacc)  # type: ignore[attr-defined]
            self.accel_t.append(msg.time_usec / 1e6)  # type: ignore[attr-defined]
            self.accel.append(math.sqrt(sum(v * v for v in a)) * 9.80665 / 1000.0)
        elif kind == "ATTITUDE":
            self.pitch_t.append(msg.time_boot_ms / 1000.0)  # type: ignore[attr-defined]
            self.pitch_deg.append(math.degrees(msg.pitch))  # type: ignore[attr-defined]
        elif kind == "SERVO_OUTPUT_RAW":
            self.servo_t.append(msg.time_usec / 1e6)  # type: ignore[attr-defined]
            self.servo.append([getattr(msg, f"servo{i}_raw") for i in range(1, 5)])


def uphill_angle_before_cut(tele: Telemetry, history: list[dict], uphill: tuple[int, ...]) -> float | None:
    """The uphill legs' mean angle in the board's last report before the cut."""
    t_cut = next((h["t"] for h in history if h["to"] == "CUT"), None)
    if t_cut is None:
        return None
    before = [a for t, a in zip(tele.legs_t, tele.leg_angle, strict=True) if t < t_cut]
    if not before:
        return None
    return sum(before[-1][i] for i in uphill) / len(uphill)


def first_contact_speed(
    tele: Telemetry,
    t_from: float,
    t_to: float,
    spike_mps2: float,
    t_impact: float | None = None,
    t_cut: float | None = None,
) -> float | None:
    """Vertical speed (m/s, down) at the first foot contact, the first accelerometer reading
    between ``t_from`` and ``t_to`` (vehicle time) that the script's impact rule calls one: above
    ``spike_mps2``, or above the lowest reading since ``t_cut`` (the motors' cut; default
    ``t_from``) by ``spike_mps2`` less 1 g (docs/onboard-script.md), or ``POWERED_TOUCH_MPS2``
    above 1 g at any time: a foot on the roof under power (the uphill foot of a steep roof can
    touch before the thrust has gone, at 1.6-1.9 g, and the script reverses at the harder contact
    that follows). With ``t_impact``, the on-board
    script's impact (the companion's REVERSE): a first touch whose 50 Hz RAW_IMU samples all stayed
    under ``spike_mps2`` (the script reads every IMU sample, the telemetry a few) is still the
    contact, found as the highest reading above 1 g in the 50 ms up to it; without this a later,
    harder second contact was measured instead.

    The velocity is reported at 50 Hz, too seldom for a fall: from the last report before the
    contact the speed is carried on with the accelerometer, ``g - |a|`` per sample (free fall reads
    0 g), up to where the reading first rose above 1 g, the start of the contact. This is the
    speed the model and the table call the impact speed; a faster descent after it (the vehicle
    pivoting onto its downhill foot) belongs to the landing, not to its start."""
    acc = list(zip(tele.accel_t, tele.accel, strict=True))
    last = t_to if t_impact is None else min(t_to, t_impact)

    from slopelander.controller.impact import ImpactDetector

    def first_impact(until: float) -> int | None:
        detector = ImpactDetector(spike_mps2)  # the script's rule, from the cut
        after_cut = max(t_from, t_cut) if t_cut is not None else t_from
        detector.arm_after_cut(math.nextafter(after_cut, -math.inf))
        for k, (t, a) in enumerate(acc):
            if t > until:
                return None
            if t < t_from:
                continue
            if a > G_MPS2 + POWERED_TOUCH_MPS2:  # a foot on the roof, the thrust still on or not
                return k
            # the log keeps magnitudes only: each is taken as pointing up the body
            if t >= after_cut and detector.feed(t, 0.0, 0.0, -a) is not None:
                return k
        return None

    spike = first_impact(last)
    if spike is None and t_impact is not None:
        near = [k for k, (t, a) in enumerate(acc) if t_impact - 0.05 <= t <= t_impact and a > G_MPS2]
        spike = max(near, key=lambda k: acc[k][1]) if near else None
    if spike is None and t_impact is not None:
        spike = first_impact(t_to)
    if spike is None:
        return None
    onset = spike
    while onset > 0 and acc[onset - 1][1] > G_MPS2 + ONSET_MPS2 and acc[onset - 1][0] >= t_from:
        onset -= 1
    t_onset = acc[onset][0]
    # the filtered reading rises a filter's delay after the contact: the speed is taken before it
    before = [(t, -v) for t, v in zip(tele.t, tele.vz_up, strict=True) if t <= t_onset - FILTER_DELAY_S]
    if not before:
        return None
    t_prev, speed = before[-1]
    for t, a in acc[:onset]:
        if t > t_prev:
            speed += (G_MPS2 - a) * (t - t_prev)
            t_prev = t
    return speed


def landing_figures(
    tele: Telemetry, history: list[dict], spike_mps2: float
) -> tuple[float | None, float | None, float | None]:
    """Impact speed (at the first contact), slide along the roof after the cut, lowest pitch
    while on the roof: read from the vehicle's own telemetry."""
    times = {h["to"]: h["t"] for h in history}
    t_cut, t_landed, t_armed = times.get("CUT"), times.get("LANDED"), times.get("ARMED")
    if t_cut is None or t_landed is None or t_armed is None:
        return None, None, None
    impact = first_contact_speed(tele, t_armed, t_landed, spike_mps2, times.get("REVERSE"), t_cut)
    xs = [x for t, x in zip(tele.x_t, tele.x, strict=True) if t_cut + 0.05 <= t <= t_landed]
    slide = (max(xs) - min(xs)) if xs else None
    pitches = [p for t, p in zip(tele.pitch_t, tele.pitch_deg, strict=True) if t_cut <= t <= t_landed]
    return impact, slide, (min(pitches) if pitches else None)
