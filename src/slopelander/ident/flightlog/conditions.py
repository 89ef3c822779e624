"""A landing's conditions from its log, each with where it came from.

- **Slope**: the rangefinder's points on the surface from the passes over the roof before
  contact, each placed with the estimator's attitude and position of its moment, fitted by the
  companion's own estimator (:mod:`slopelander.controller.slope_estimate`,
  docs/slope-estimate.md: a plane, read along the vehicle's heading; a line along the heading when
  the passes ran one way), at the spot where the body was at contact.
- **Impact**: the estimator's velocity at its last sample before contact, carried to contact by
  the accelerometer (turned into the earth frame); pitch and pitch rate from the attitude and
  the gyro at contact. Horizontal speed is along the heading (the model's x, downhill).
- **Legs**: the friction torques from the companion's ``SL LEGS_WAIT`` message (DataFlash logs
  keep the companion's STATUSTEXT), or ``transitions.jsonl`` beside the log (a tlog holds only
  what the autopilot sent); the leg angles are in neither log: the shipped lookup table's, as the
  companion sets them, unless given.
- **Reverse thrust as flown**: from the script's states (RVT at impact, HOLD at the end of its
  ramp) and the motor outputs (the percent, 1500 - 5 N µs; the ramp's start from the rising
  outputs).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from slopelander.controller.slope_estimate import (
    EstimateSettings,
    SlopeEstimate,
    beam_point,
    estimate,
    estimate_plane,
)
from slopelander.ident.flightlog.landings import (
    DEADBAND_US,
    FAULT_HELD,
    HOLD,
    NEUTRAL_US,
    LandingEvents,
)
from slopelander.ident.flightlog.reader import FlightLog, FlightLogError
from slopelander.model import ConditionError, LandingConditions
from slopelander.model.conditions import MAX_REVERSE_DURATION, MAX_REVERSE_RAMP

TORQUES = re.compile(r"legs commanded to (\d+(?:\.\d+)?)/(\d+(?:\.\d+)?) N\*m")
#: the legs' angles as the board reported them when they reached their preset (controller/states/legs_wait.py)
ANGLES = re.compile(r"legs within tolerance at (-?\d+(?:\.\d+)?)/(-?\d+(?:\.\d+)?) deg")
"""The reason of the companion's move to LEGS_WAIT, which names the friction torques it commanded
(controller/states/preset.py); its STATUSTEXT is ``SL LEGS_WAIT: <reason>``."""
LATERAL_M = 1.0
"""Surface points farther than this across the heading from the landing spot are not used."""
PASS_SPEED_MPS = 0.1
"""Surface points count toward the slope only while the vehicle moves along its heading this fast."""
POINT_WINDOW_S = 0.1
"""A range reading is placed with the attitude and position interpolated within this of it."""


@dataclass
class Given:
    """What the user gave on the command line in place of the log's (None: read it)."""

    slope_deg: float | None = None
    tau: tuple[float, float] | None = None
    angles: tuple[float, float] | None = None


@dataclass
class Conditions:
    """The model's conditions for a landing, where each came from, and what to keep in mind."""

    conditions: LandingConditions
    sources: dict[str, str]
    slope: SlopeEstimate | None
    heading_rad: float
    notes: list[str] = field(default_factory=list)


def heading(log: FlightLog, t0: float, t1: float) -> float:
    """The vehicle's mean yaw (rad) over ``t0..t1``, as a circular mean."""
    s = log.attitude.between(t0, t1)
    if not len(s):
        s = log.attitude
    yaw = s.v[:, 2]
    return float(math.atan2(np.mean(np.sin(yaw)), np.mean(np.cos(yaw))))


def surface_points(log: FlightLog, until: float) -> list[tuple[float, float, float, float]]:
    """(t, north m, east m, height up m) of every range reading in range before ``until``, placed
    with the estimator's attitude and position interpolated to its time from samples within
    :data:`POINT_WINDOW_S` of it."""
    r, e = log.ranges, log.ekf
    if not (len(r) and len(e)):
        return []
    keep = (r.t < until) & (r.v[:, 1] > 0.5)
    t, d = r.t[keep], r.v[keep, 0]
    i = np.searchsorted(e.t, t)
    inside = (i > 0) & (i < len(e.t))
    i = np.clip(i, 1, len(e.t) - 1)
    near = inside & (e.t[i] - t <= POINT_WINDOW_S) & (t - e.t[i - 1] <= POINT_WINDOW_S)
    yaw_s, yaw_c = np.interp(t, e.t, np.sin(e.v[:, 8])), np.interp(t, e.t, np.cos(e.v[:, 8]))
    cols = [np.interp(t, e.t, e.v[:, k]) for k in (3, 4, 5, 6, 7)]
    out = []
    for j in np.nonzero(near)[0]:
        n, ea, dn, roll, pitch = (float(x[j]) for x in cols)
        if not (math.isfinite(roll) and math.isfinite(pitch)):
            continue
        yaw = math.atan2(yaw_s[j], yaw_c[j])
        pn, pe, pd = beam_point(float(d[j]), roll, pitch, yaw, n, ea, dn)
        out.append((float(t[j]), pn, pe, -pd))
    return out


def measure_slope(
    log: FlightLog,
    contact: float,
    psi: float,
    settings: EstimateSettings | None = None,
    since: float = -math.inf,
) -> tuple[SlopeEstimate, str]:
    """The slope along the heading at the body's position at contact, and how it was fitted.

    The points are those taken before contact while the vehicle moved (:data:`PASS_SPEED_MPS`):
    hovering and the vertical descent see one spot of the roof, and the estimator's slow height
    drift over those seconds would read as slope. They are fitted as the companion fits them, by a
    plane (:func:`estimate_plane`) read along the heading; a log whose passes ran one way only
    (an approach, or a companion before the two-leg survey) is fitted by a line along the heading
    (:func:`estimate`, the points within :data:`LATERAL_M` of it). Only points after ``since``
    count: in a log of several landings, those before the previous one's end saw another roof."""
    e = log.ekf
    n0, e0 = float(e.at(contact, 3)), float(e.at(contact, 4))
    moving = [
        p
        for p in surface_points(log, contact)
        if p[0] > since and math.hypot(float(e.at(p[0], 0)), float(e.at(p[0], 1))) >= PASS_SPEED_MPS
    ]
    plane = estimate_plane(moving, (n0, e0), settings)
    if plane.ok or not plane.needs_survey:
        return plane.along(math.degrees(psi)), "plane"
    c, s = math.cos(psi), math.sin(psi)
    across0 = -n0 * s + e0 * c
    line = [(t, n * c + ea * s, h) for t, n, ea, h in moving if abs(-n * s + ea * c - across0) <= LATERAL_M]
    est = estimate(line, n0 * c + e0 * s, settings)
    if not est.ok:
        est.refusal = f"{plane.refusal}; along the heading alone: {est.refusal}"
    return est, "line along the heading (the passes ran one way)"


def _rotate(roll: float, pitch: float, yaw: float, f: np.ndarray) -> np.ndarray:
    """Body (forward, right, down) to earth (north, east, down), ArduPilot's 3-2-1 Euler angles."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    R = np.array(
        [
            [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
            [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
            [-sp, sr * cp, cr * cp],
        ]
    )
    return R @ f


def impact_velocity(log: FlightLog, contact: float) -> tuple[np.ndarray, float]:
    """Velocity (north, east, down; m/s) at ``contact``: the estimator's last sample before it,
    plus the accelerometer's earth-frame acceleration integrated from there; and how long that
    integration ran (s)."""
    e = log.ekf
    i = int(np.searchsorted(e.t, contact, side="right")) - 1
    if i < 0:
        raise FlightLogError(log.path, f"no velocity ({e.source}) before contact at {contact:.3f} s")
    t0 = float(e.t[i])
    v = e.v[i, :3].astype(float).copy()
    imu = log.imu.between(t0, contact)
    g = np.array([0.0, 0.0, 9.80665])
    prev_t, prev_a = None, None
    for t, row in zip(imu.t, imu.v, strict=True):
        att = [float(log.attitude.at(t, k)) for k in range(3)]
        a = _rotate(*att, row[3:6]) + g
        if prev_t is not None:
            v += 0.5 * (a + prev_a) * (t - prev_t)
        prev_t, prev_a = t, a
    if prev_t is not None and prev_t < contact:
        v += prev_a * (contact - prev_t)
    return v, contact - t0


def preset_torques(log: FlightLog, before: float) -> tuple[tuple[float, float], str] | None:
    """The torques the companion commanded last before ``before``, and where it said so."""
    return _companion_pair(log, before, "LEGS_WAIT", TORQUES)


def preset_angles(log: FlightLog, before: float) -> tuple[tuple[float, float], str] | None:
    """The legs' (uphill, downhill) angles the board reported last before ``before`` as they reached
    their preset, and where the companion said so."""
    return _companion_pair(log, before, "CHECKS", ANGLES)


def _companion_pair(
    log: FlightLog, before: float, state: str, pattern: re.Pattern
) -> tuple[tuple[float, float], str] | None:
    """Two numbers the companion gave in its last transition to ``state`` before ``before``: from
    its STATUSTEXT, which ArduPilot logs (MSG, "SRC=..:SL STATE: reason"), else from the landing's
    transitions.jsonl beside the log."""
    found = None
    for t, text in log.texts:
        if t > before:
            break
        m = pattern.search(text) if f"SL {state}:" in text else None
        if m:
            found = ((float(m.group(1)), float(m.group(2))), f"the companion's message at {t:.2f} s")
    if found is not None:
        return found
    beside = log.path.parent / "transitions.jsonl"
    if beside.is_file():
        from slopelander.controller.session import read_transitions

        last = None
        for entry in read_transitions(beside):
            m = pattern.search(str(entry.get("reason", ""))) if entry.get("to") == state else None
            t = entry.get("t")
            if m and isinstance(t, (int, float)) and t <= before:
                last = ((float(m.group(1)), float(m.group(2))), f"{beside.name} beside the log ({t:.2f} s)")
        return last
    return None


def table_angles(slope_deg: float, speed: float) -> tuple[float, float]:
    """The shipped lookup table's leg angles (uphill, downhill) for this slope and speed (the
    speed held within the table's range: the angle follows the slope)."""
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable

    table = LookupTable.load(DEFAULT_TABLE)
    lo, hi = table.speed_range
    p = table.lookup(slope_deg, min(max(speed, lo), hi))
    return p.angle_up_deg, p.angle_down_deg


def reverse_as_flown(log: FlightLog, ev: LandingEvents, contact: float) -> tuple[dict, str, list[str]]:
    """The reverse thrust as flown, as LandingConditions fields, where it came from, and notes."""
    notes: list[str] = []
    if ev.reverse is None:
        return {"reverse_percent": 0.0}, "no reverse thrust in the log (the script went to HOLD)", notes
    o = log.outputs
    end = ev.reverse_left if ev.reverse_left is not None else ev.end
    during = o.between(ev.reverse, end)
    rev = during.v[np.all(during.v < NEUTRAL_US - DEADBAND_US, axis=1)] if len(during) else np.zeros((0, 4))
    if not len(rev):
        raise FlightLogError(
            log.path,
            f"landing {ev.number}: reverse thrust from {ev.reverse:.3f} s, but no motor output "
            f"({o.source}) below {NEUTRAL_US - DEADBAND_US} µs logged during it: its percent is unknown",
        )
    low = float(rev.mean(axis=1).min())  # the plateau: the ramp only rises from it
    pct = min(100.0, (NEUTRAL_US - low) / 5.0)
    delay = max(0.0, ev.reverse - contact)
    fields = {"reverse_percent": round(pct, 1), "reverse_delay": delay}
    how = f"{o.source} at {low:.0f} µs, " + (
        "the script's states" if ev.cut_source.startswith(log.states.source) else "their timing"
    )
    if ev.reverse_left is None:
        notes.append("the log ends during the reverse thrust: it is held to the model's horizon")
        return fields, how, notes
    if ev.reverse_left_to not in (HOLD, FAULT_HELD):
        # disarmed, the emergency stop, or given back: the outputs stopped at once
        fields["reverse_duration"] = min(MAX_REVERSE_DURATION, max(1e-3, ev.reverse_left - ev.reverse))
        return fields, how, notes
    if ev.reverse_left_to == FAULT_HELD:
        # the script's update failed in RVT: it ramps the thrust down from then (onboard-script.md)
        ramp = o.between(ev.reverse_left, ev.end)
        mean = ramp.v.mean(axis=1) if len(ramp) else np.zeros(0)
        rising = (mean > low + 5.0) & (mean < NEUTRAL_US - DEADBAND_US)
        length = 0.0
        if np.count_nonzero(rising) >= 2:
            b, _ = np.polyfit(ramp.t[rising], mean[rising], 1)
            length = (NEUTRAL_US - low) / b if b > 0 else 0.0
        else:
            notes.append("the faulted script's ramp down was not resolved by the outputs: taken as a step")
        fields["reverse_duration"] = min(MAX_REVERSE_DURATION, max(1e-3, ev.reverse_left - ev.reverse))
        fields["reverse_ramp"] = min(MAX_REVERSE_RAMP, length)
        notes.append(f"the on-board script faulted in its reverse thrust at {ev.reverse_left:.3f} s")
        return fields, how, notes
    # HOLD comes at the end of the ramp; the ramp began where a line through the rising outputs
    # meets the plateau
    ramp = o.between(ev.reverse, ev.reverse_left)
    mean = ramp.v.mean(axis=1) if len(ramp) else np.zeros(0)
    rising = (mean > low + 5.0) & (mean < NEUTRAL_US - DEADBAND_US)
    start = None
    if np.count_nonzero(rising) >= 2:
        b, a = np.polyfit(ramp.t[rising], mean[rising], 1)
        if b > 0:
            start = (low - a) / b
    if start is None:
        plateau = ramp.t[~rising & (mean <= low + 5.0)]
        start = float(plateau[-1]) if len(plateau) else ev.reverse
        notes.append(
            f"the reverse thrust's ramp was not resolved by the {o.rate_hz:.0f} Hz outputs: "
            "taken to start at the last full-thrust sample"
        )
    start = min(max(start, ev.reverse + 1e-3), ev.reverse_left)
    fields["reverse_duration"] = min(MAX_REVERSE_DURATION, start - ev.reverse)
    fields["reverse_ramp"] = max(0.0, ev.reverse_left - start)
    return fields, how, notes


def landing_conditions(log: FlightLog, ev: LandingEvents, contact: float, given: Given) -> Conditions:
    """The model's :class:`LandingConditions` for landing ``ev`` with first contact at ``contact``."""
    notes: list[str] = []
    sources: dict[str, str] = {}
    psi = heading(log, ev.cut - 2.0, contact)
    slope = None
    if given.slope_deg is not None:
        slope_deg = given.slope_deg
        sources["slope"] = "given"
    else:
        slope, fitted = measure_slope(log, contact, psi, since=ev.since)
        if not slope.ok:
            raise FlightLogError(
                log.path,
                f"landing {ev.number}: the log does not show the roof well enough to measure its slope "
                f"({slope.refusal}): give --slope DEG",
            )
        slope_deg = float(slope.slope_deg)
        sources["slope"] = (
            f"{log.ranges.source} over the roof, {fitted}: {slope.n_inliers}/{slope.n_points} points, "
            f"+-{slope.sigma_deg:.1f} deg"
        )
    v, carried = impact_velocity(log, contact)
    c, s = math.cos(psi), math.sin(psi)
    speed = float(v[2])
    horizontal = float(v[0] * c + v[1] * s)
    sources["impact"] = f"{log.ekf.source} {1000 * carried:.0f} ms before contact, {log.imu.source} since"
    pitch = math.degrees(float(log.attitude.at(contact, 1)))
    rate = math.degrees(float(log.imu.at(contact, 1)))
    sources["attitude"] = f"{log.attitude.source}, {log.imu.source} gyro"
    if given.tau is not None:
        tau = given.tau
        sources["legs"] = "given"
    else:
        found = preset_torques(log, contact)
        if found is None:
            raise FlightLogError(
                log.path,
                f"landing {ev.number}: the log does not say the legs' friction torques (no companion "
                "'SL LEGS_WAIT' message in it, no transitions.jsonl beside it): "
                "give --tau-up UP --tau-down DOWN",
            )
        tau, sources["legs"] = found
    reported = None if given.angles is not None else preset_angles(log, contact)
    if given.angles is not None:
        angles = given.angles
        sources["leg angles"] = "given"
    elif reported is not None:
        # the board reads a leg at its stop within its sensor's tenths of a degree: held to the
        # joint's range (LandingConditions.validate), 0..37.5 deg
        angles = tuple(min(max(a, 0.0), 37.5) for a in reported[0])
        sources["leg angles"] = f"as the leg board reported them, {reported[1]}"
    else:
        try:
            angles = table_angles(slope_deg, speed)
        except ValueError as exc:
            raise FlightLogError(
                log.path,
                f"landing {ev.number}: no leg angles for it ({exc}): give --angle-up UP --angle-down DOWN",
            ) from None
        sources["leg angles"] = "not in the log: the shipped lookup table's for this slope"
    thrust, sources["reverse thrust"], more = reverse_as_flown(log, ev, contact)
    notes += more
    from_states = ev.cut_source.startswith(log.states.source)
    if not from_states:
        notes.append(
            f"the script's states are not in the log: the cut and the reverse thrust are timed by the "
            f"{log.outputs.rate_hz:.0f} Hz motor outputs"
        )
    elif ev.cut > contact + 0.005:
        notes.append(
            f"the motors were cut {1000 * (ev.cut - contact):.0f} ms after first contact: the model's "
            "landing starts with them stopped"
        )
    try:
        cond = LandingConditions(
            slope_deg=round(slope_deg, 2),
            speed=max(0.0, speed),
            horizontal_speed=horizontal,
            pitch_deg=pitch,
            pitch_rate_dps=rate,
            tau_up=tau[0],
            tau_down=tau[1],
            angle_up_deg=angles[0],
            angle_down_deg=angles[1],
            **thrust,
        )
        cond.validate()
    except ConditionError as exc:
        raise FlightLogError(log.path, f"landing {ev.number}: {exc}") from None
    return Conditions(cond, sources, slope, psi, notes)
