"""The roof as a plane: how far the vehicle rose over it, and which plane the landing knows.

The take-off counts its climb over the roof it leaves (a take-off from a slope drifts downhill),
and the descent's stuck-range check counts the approach to the roof it flies over (a descent that
drifts downhill sees the range fall slower than it descends). Both read LOCAL_POSITION_NED and the
same plane: the survey's, else the landing's slope along a heading."""

from __future__ import annotations

import math
from typing import Any


def rise_over_roof(
    start: tuple[float, float, float],
    now: tuple[float, float, float],
    slope_deg: float | None,
    heading_deg: float | None,
    cross_deg: float | None = None,
) -> float:
    """How far (m) the vehicle rose over the roof plane through the spot it took off from, by
    LOCAL_POSITION_NED (north-east-down) and the roof: ``slope_deg`` along ``heading_deg`` (deg
    from north; positive: falling the way the vehicle faces, as it lands) and ``cross_deg`` across
    it (positive: falling to the right). Leaving a slope the tilted body is pushed downhill and
    the roof falls away below it: on ArduCopter a take-off from a 35 deg roof drifted 3.4 m
    downhill and ended 0.85 m *lower* than it began, 1.5 m over the roof. Without a slope or a
    heading only the height itself counts (a drift uphill would otherwise be credited)."""
    dn, de, dd = (b - a for a, b in zip(start, now, strict=True))
    rise = -dd  # NED: up is a smaller z
    if slope_deg is None or heading_deg is None:
        return rise
    h = math.radians(heading_deg)
    along = dn * math.cos(h) + de * math.sin(h)  # the way the vehicle faces
    right = -dn * math.sin(h) + de * math.cos(h)
    fall = along * math.tan(math.radians(slope_deg)) + right * math.tan(math.radians(cross_deg or 0.0))
    return rise + fall if math.isfinite(fall) else rise


def roof_plane(
    measured: Any, slope_deg: float | None, heading_deg: float | None
) -> tuple[float | None, float | None, float | None]:
    """The roof a landing knows: (slope along the heading, heading, cross-slope), deg. The survey's
    plane (``measured``, a slope estimate with ``slope_deg``, ``heading_deg`` and ``cross_deg``)
    when there is one; else ``slope_deg`` along ``heading_deg``; None where unknown."""
    heading, slope = getattr(measured, "heading_deg", None), getattr(measured, "slope_deg", None)
    if heading is not None and slope is not None:
        return slope, heading, getattr(measured, "cross_deg", None)
    return slope_deg, heading_deg, None


def beam_direction(roll: float, pitch: float, yaw: float) -> tuple[float, float, float]:
    """The downward rangefinder's beam (the body's z axis) as a unit vector north-east-down, from
    ATTITUDE's roll, pitch and yaw (rad; ArduPilot's Z-Y-X Euler angles)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return (cr * sp * cy + sr * sy, cr * sp * sy - sr * cy, cr * cp)


def height_from_beam(
    range_m: float,
    beam: tuple[float, float, float],
    slope_deg: float | None,
    heading_deg: float | None,
    cross_deg: float | None = None,
) -> float:
    """The vertical height (m) over the roof plane below the vehicle that a reading of
    ``range_m`` along ``beam`` (:func:`beam_direction`) means, for the roof of
    :func:`roof_plane` (unknown: level). The plane's depth grows by ``a`` per metre north and ``b``
    per metre east; the beam meets it after ``range = height / (b_d - a b_n - b b_e)``. Over a
    steep roof the body's pitch moves the reading a lot: nose up 5 deg over a 43 deg roof falling
    ahead, a reading of 1.48 m is 1.33 m of height, level it would be 1.48 m."""
    a = b = 0.0
    if slope_deg is not None and heading_deg is not None:
        h = math.radians(heading_deg)
        ts, tc = math.tan(math.radians(slope_deg)), math.tan(math.radians(cross_deg or 0.0))
        a = ts * math.cos(h) - tc * math.sin(h)
        b = ts * math.sin(h) + tc * math.cos(h)
    bn, be, bd = beam
    return range_m * (bd - a * bn - b * be)
