"""TAKEOFF turns a range read along a tilted body into a height over the slope before it loosens
the legs (found while chasing the soak's last low loosenings: within the 10 deg allowed, a beam
tilted downhill over a 44 deg roof reads 1.22 times the height)."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from slopelander.controller.states.takeoff import height_over_slope
from tests.controller.test_machine import OK, _to_takeoff, up


def beam_length(height_m: float, slope_deg: float, tilt_deg: float, azimuth_deg: float) -> float:
    """Where a beam along a body tilted ``tilt_deg`` toward ``azimuth_deg`` (0: uphill) meets the
    plane rising at ``slope_deg``, from a body ``height_m`` straight above it; inf if it never does."""
    a, t, p = (math.radians(v) for v in (slope_deg, tilt_deg, azimuth_deg))
    den = math.cos(t) - math.sin(t) * math.cos(p) * math.tan(a)
    return height_m / den if den > 1e-9 else math.inf


@given(
    height=st.floats(0.05, 5.0),
    slope=st.floats(0.0, 60.0),
    tilt=st.floats(0.0, 20.0),
    azimuth=st.floats(0.0, 360.0),
)
def test_the_height_never_exceeds_the_true_one_whichever_way_the_body_tilts(height, slope, tilt, azimuth):
    # azimuth 0 here is a beam tilted uphill: the formula's "downhill" is azimuth 180
    r = beam_length(height, slope, tilt, azimuth + 180.0)
    if math.isfinite(r):
        assert height_over_slope(r, tilt, slope) <= height * (1 + 1e-9)


@pytest.mark.parametrize("slope, tilt", [(0.0, 0.0), (18.3, 9.0), (44.0, 10.0), (55.0, 5.0)])
def test_a_beam_tilted_downhill_gives_the_true_height(slope, tilt):
    r = beam_length(0.7, slope, tilt, 0.0)  # tilted downhill: the longest reading
    assert height_over_slope(r, tilt, slope) == pytest.approx(0.7)


def test_a_beam_along_the_slope_is_no_height():
    assert height_over_slope(3.0, 40.0, 60.0) == 0.0


@pytest.mark.parametrize("args", [(3.0, 5.0, math.nan), (3.0, math.nan, 30.0)])
def test_a_height_from_a_number_that_is_not_finite_is_none(args):
    assert height_over_slope(*args) == 0.0


def _climb(slope, tilt, reading):
    """Climb at 1 m/s from the roof to ``reading`` and hover there, the body tilted ``tilt``."""
    m, t = _to_takeoff()
    m.ctx.slope_deg = slope
    rng = 0.1
    for _ in range(200):
        t += 0.02
        rng = min(reading, rng + 0.02)
        if m.step(replace(OK, t=t, range_m=rng, tilt_deg=tilt, position_m=up(rng - 0.1))) != "TAKEOFF":
            break
    return m


def test_a_long_reading_of_a_tilted_beam_over_a_steep_roof_does_not_loosen_the_legs():
    # 0.87 m, read 8 deg downhill of level over a 44 deg roof: the body is at most 0.75 m over it
    assert _climb(44.0, 8.0, 0.87).name == "TAKEOFF"
    m = _climb(44.0, 8.0, 1.0)  # at least 0.86 m over it: clear
    assert m.history[-1]["to"] == "RESET"
    assert "over the 44 deg slope" in m.history[-1]["reason"]


def test_a_landing_not_told_its_slope_assumes_the_steepest():
    m = _climb(None, 8.0, 1.0)  # over 60 deg: at least 0.75 m, not clear
    assert m.name == "TAKEOFF"
    assert m.ctx.cfg["takeoff.unknown_slope_deg"] == 60
