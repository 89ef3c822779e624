"""The plane under the spot (both gradients, the fall line, the slope along the vehicle's heading
and across it) on synthesized survey passes: a roof whose fall line is not the heading is read
as the plane it is, never as a flat roof along the heading, and a landing across it is refused
with the plane's figures."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slopelander.controller.config import load_config
from slopelander.controller.slope_estimate import (
    EstimateSettings,
    SurfaceTrack,
    cross_refusal,
    estimate_plane,
    fit_plane,
    pilot_refusal,
    slope_to_land,
)
from slopelander.controller.survey import measure_slope

SPOT = (5.5, 0.0)


def leg_offsets(n: int = 200) -> np.ndarray:
    """One leg as the survey flies it: spot, 1 m back, 2 m ahead, back to the spot (m along it)."""
    return np.concatenate([np.linspace(0, -1, n // 4), np.linspace(-1, 1, n // 2), np.linspace(1, 0, n // 4)])


def surface(n: float, e: float, slope_deg: float, fall_deg: float) -> float:
    """Height of a plane through the spot at height 0 falling ``slope_deg`` toward ``fall_deg``."""
    f = math.radians(fall_deg)
    return -math.tan(math.radians(slope_deg)) * ((n - SPOT[0]) * math.cos(f) + (e - SPOT[1]) * math.sin(f))


def track_of_pass(
    slope_deg: float,
    fall_deg: float,
    headings: tuple[float, ...],
    height: float = 2.0,
    seed: int = 0,
    walk: float = 0.01,
    bias_deg: float = 0.5,
    noise_deg: float = 0.2,
    range_noise: float = 0.005,
    beside: tuple[float, ...] = (),
) -> SurfaceTrack:
    """A pass of one leg per heading (each flown facing its heading) at 20 Hz, level, with the
    errors a real vehicle has: the height wandering as a random walk of ``walk`` m per sqrt(s), a
    per-pass attitude bias (1 sigma ``bias_deg`` on roll and on pitch), attitude noise and range
    noise. The true beam is vertical; the points are placed by :class:`SurfaceTrack` from the
    attitude (yaw included) and the position."""
    rng = np.random.default_rng(seed)
    dt = 0.05
    rows = []
    for k, heading in enumerate(headings):
        a = math.radians(heading)
        off = beside[k] if k < len(beside) else 0.0
        n0, e0 = SPOT[0] - off * math.sin(a), SPOT[1] + off * math.cos(a)
        rows += [(n0 + s * math.cos(a), e0 + s * math.sin(a), a) for s in leg_offsets()]
    drift = np.cumsum(rng.normal(0.0, walk * math.sqrt(dt), len(rows)))
    bias = np.radians(rng.normal(0.0, bias_deg, 2))
    tr = SurfaceTrack(0.1)
    for i, (n, e, yaw) in enumerate(rows):
        t = i * dt
        roll, pitch = bias + np.radians(rng.normal(0.0, noise_deg, 2))
        tr.add(t, attitude=(float(roll), float(pitch), yaw), position=(n, e, -(height + drift[i])))
        true = height - surface(n, e, slope_deg, fall_deg)
        tr.add(t + 0.001, range_m=true + rng.normal(0.0, range_noise))
    return tr


def test_a_roof_falling_east_does_not_read_flat_and_confident() -> None:
    """Issue 40, finding 4: the survey measured along north only, so a 45 deg roof falling east
    read 0.0 +/- 0.8 deg from a pass along north, was trusted, and the 0 deg preset was flown onto
    it. From the same pass the slope across it is unseen: refused, and a survey pass is asked
    for (it flies a second leg across)."""
    tr = track_of_pass(45.0, 90.0, headings=(0.0,), seed=1)
    est, took = measure_slope(None, load_config(), tr, fly=False, tick=lambda: None, note=lambda _: None)
    assert took == 0.0
    assert not est.ok and est.slope_deg is None, est.describe()
    assert est.needs_survey and "across" in est.refusal, est.refusal


def test_both_legs_read_the_plane_and_refuse_a_landing_across_it_with_the_figures() -> None:
    """With a second leg across, the plane is read: 45 deg falling east. Facing north (not turned:
    ``fly=False``) the slope along the heading is 0 and 45 deg lies across it: refused, naming the
    plane, the heading and the way to face."""
    tr = track_of_pass(45.0, 90.0, headings=(0.0, 90.0), seed=2)
    est, _ = measure_slope(None, load_config(), tr, fly=False, tick=lambda: None, note=lambda _: None)
    assert est.plane_slope_deg == pytest.approx(45.0, abs=2 * est.plane_sigma_deg)
    assert est.fall_azimuth_deg == pytest.approx(90.0, abs=2.0)
    assert est.heading_deg == pytest.approx(90.0)  # the attitude's newest yaw: the second leg's
    # the heading the vehicle has is the second leg's: the plane along it is the full slope
    assert est.ok and est.slope_deg == pytest.approx(45.0, abs=2.0) and abs(est.cross_deg) < 1.0
    north = estimate_plane(tr.surface_points(), SPOT).along(0.0)
    why = cross_refusal(north, 3.0)
    assert why is not None
    assert f"falls {north.plane_slope_deg:.1f} +/- " in why and "toward 90 deg (east)" in why, why
    assert f"heading 0 deg: {north.slope_deg:.1f} deg along it, {north.cross_deg:.1f} deg across" in why, why
    assert "face 90 deg (east)" in why, why


@pytest.mark.parametrize("fall", [0.0, 37.0, 90.0, 200.0, 315.0])
def test_the_slope_along_any_heading_and_across_it(fall: float) -> None:
    """The plane gives the section along a heading, atan(tan(slope) cos(heading - fall)), and
    across it, atan(tan(slope) sin(heading - fall)) (positive: falling to the vehicle's right)."""
    tr = track_of_pass(30.0, fall, headings=(10.0, 100.0), seed=3, walk=0.0, bias_deg=0.0)
    plane = estimate_plane(tr.surface_points(), SPOT)
    assert plane.ok, plane.refusal
    t = math.tan(math.radians(30.0))
    for heading in (0.0, 45.0, 90.0, 180.0, 300.0):
        est = plane.along(heading)
        d = math.radians(heading - fall)
        assert est.slope_deg == pytest.approx(math.degrees(math.atan(t * math.cos(d))), abs=0.3)
        assert est.cross_deg == pytest.approx(-math.degrees(math.atan(t * math.sin(d))), abs=0.3)
    assert (
        math.isclose(plane.fall_azimuth_deg, fall % 360, abs_tol=1.0)
        or abs(plane.fall_azimuth_deg - fall) > 359
    )


def test_facing_the_fall_line_the_pilots_figure_is_checked_along_the_heading() -> None:
    """``--slope N`` is checked against the slope along the heading the vehicle has: facing the
    fall line of a 45 deg roof a pilot's 45 passes and 0 is refused, naming the heading; facing
    north across it, the cross-slope refuses first."""
    plane = estimate_plane(track_of_pass(45.0, 90.0, headings=(0.0, 90.0), seed=4).surface_points(), SPOT)
    east = plane.along(90.0)
    assert pilot_refusal(45.0, east, 4.5) is None
    why = pilot_refusal(0.0, east, 4.5)
    assert why is not None and "pilot's slope 0 deg" in why and "along heading 90 deg" in why, why
    assert slope_to_land(east, 4.5)[0] == pytest.approx(45.0, abs=2.0)
    west = plane.along(270.0)  # facing uphill
    slope, why = slope_to_land(west, 4.5)
    assert slope is None and "back" in why and "downhill (east)" in why, why


def test_the_stated_interval_covers_the_plane_at_its_rate() -> None:
    """Over 150 two-leg passes with a height wander, an attitude bias and noise, at random fall
    lines: 2 sigma of the slope along the heading (the landing's) holds at least 92 % of the
    errors (95 % stated), 2 sigma of the cross-slope too, and the stated sigma says something (it
    stays within twice the spread)."""
    rng = np.random.default_rng(7)
    errs, sig, cross_errs, cross_sig = [], [], [], []
    for seed in range(150):
        slope, fall, heading = (
            float(rng.uniform(0, 45)),
            float(rng.uniform(0, 360)),
            float(rng.uniform(0, 360)),
        )
        tr = track_of_pass(slope, fall, headings=(heading, heading + 90.0), seed=seed)
        est = estimate_plane(tr.surface_points(), SPOT).along(heading)
        assert est.ok, est.describe()
        t, d = math.tan(math.radians(slope)), math.radians(heading - fall)
        errs.append(est.slope_deg - math.degrees(math.atan(t * math.cos(d))))
        sig.append(est.sigma_deg)
        cross_errs.append(est.cross_deg + math.degrees(math.atan(t * math.sin(d))))
        cross_sig.append(est.cross_sigma_deg)
    z = np.abs(errs) / np.array(sig)
    zc = np.abs(cross_errs) / np.array(cross_sig)
    assert (z <= 2).mean() >= 0.92, ((z <= 2).mean(), np.std(errs), np.mean(sig))
    assert (zc <= 2).mean() >= 0.92, ((zc <= 2).mean(), np.std(cross_errs), np.mean(cross_sig))
    assert np.mean(sig) <= 2.0 * np.std(errs) + 0.5, (np.std(errs), np.mean(sig))


@settings(max_examples=30, deadline=None)
@given(
    slope=st.floats(0.0, 60.0),
    fall=st.floats(0.0, 360.0),
    outlier_share=st.floats(0.0, 0.25),
    seed=st.integers(0, 10_000),
)
def test_the_plane_fit_finds_the_plane_through_noise_and_outliers(slope, fall, outlier_share, seed) -> None:
    rng = np.random.default_rng(seed)
    dn, de = rng.uniform(-1.0, 1.0, 200), rng.uniform(-1.0, 1.0, 200)
    f = math.radians(fall)
    h = -math.tan(math.radians(slope)) * (dn * math.cos(f) + de * math.sin(f)) + rng.normal(0, 0.01, 200)
    bad = rng.random(200) < outlier_share
    h[bad] += rng.uniform(0.3, 2.0, bad.sum()) * rng.choice([-1, 1], bad.sum())  # dropouts read as spikes
    fit = fit_plane(dn, de, h)
    got = math.degrees(math.atan(math.hypot(*fit.gradient)))
    assert abs(got - slope) < 1.0
    if slope > 5.0:
        az = math.degrees(math.atan2(-fit.gradient[1], -fit.gradient[0])) % 360
        assert abs((az - fall + 180) % 360 - 180) < 3.0
    if bad.any():
        assert (fit.weights[bad] < 0.5).mean() > 0.9  # the outliers were found, not averaged in


def test_a_ridge_under_one_leg_is_refused() -> None:
    """A gable ridge through the spot across the second leg: the two sides of the spot along that
    leg fall different ways. Refused for what the points showed (no survey helps): a steep ridge
    leaves too few points on any one plane, a gentle one two different slopes on the two sides."""
    tr = track_of_pass(0.0, 0.0, headings=(0.0, 90.0), seed=5, walk=0.0)
    for fall, why in ((0.5, "points lie on one plane"), (0.15, "not one plane")):  # 26.6 and 8.5 deg each way
        pts = [(t, n, e, h - fall * abs(e)) for t, n, e, h in tr.surface_points()]
        plane = estimate_plane(pts, SPOT)
        assert not plane.ok and not plane.needs_survey and why in plane.refusal, plane.refusal


def test_one_plane_under_a_wandering_height_is_not_taken_for_two() -> None:
    """The two sides of the spot are told apart within the errors the whole estimate has, the
    height's slow wander included (each side is half the baseline, so the wander tilts it more).
    The side check once allowed the fit's own error alone: a 35 deg roof seen through a height
    wander of 0.03 m per sqrt(s) was refused as a ridge in 7 of these 100 passes (on ArduCopter
    SITL, in CI, once: 5.2 deg between the sides where 4.3 was allowed)."""
    st = EstimateSettings(height_walk_m=0.03)
    refused = []
    for seed in range(100):
        tr = track_of_pass(35.0, 0.0, headings=(0.0, 90.0), seed=seed, walk=0.03)
        plane = estimate_plane(tr.surface_points(), SPOT, st)
        if plane.refusal is not None:
            refused.append((seed, plane.refusal))
    assert len(refused) <= 1, refused  # measured: none


def test_a_second_leg_cut_short_is_too_little_seen() -> None:
    """A second leg that saw 0.2 m on one side (a gutter there): refused as too little seen, naming
    the way."""
    tr = track_of_pass(20.0, 90.0, headings=(0.0, 90.0), seed=6)
    pts = [p for p in tr.surface_points() if p[2] > -0.2]  # nothing seen more than 0.2 m west
    plane = estimate_plane(pts, SPOT, EstimateSettings())
    assert not plane.ok and plane.needs_survey, plane.refusal
    assert "0.2" in plane.refusal and "deg (west) of the spot" in plane.refusal, plane.refusal


def test_heading_interpolation_takes_the_short_way_across_north() -> None:
    """A reading between attitudes at 359 and 1 deg is placed with 0 deg, not 180."""
    tr = SurfaceTrack(0.1)
    tr.add(0.0, attitude=(0.0, 0.2, math.radians(359.0)), position=(0.0, 0.0, -2.0))
    tr.add(0.1, attitude=(0.0, 0.2, math.radians(1.0) - 2 * math.pi * 0), position=(0.0, 0.0, -2.0))
    tr.add(0.05, range_m=2.0)
    ((_t, n, e, _h),) = tr.surface_points()
    assert n > 0.3 and abs(e) < 0.01  # pitched nose up facing north: the point is north


@pytest.mark.parametrize("beside", [(0.0, 0.25), (0.2, -0.25)])
def test_a_leg_flown_beside_the_spot_is_still_a_leg(beside) -> None:
    """A turn on the spot can leave the vehicle a little beside it (on ArduCopter over the planar
    physics, 0.17 m: it cannot move across its heading), and the next leg is flown there: its
    points are still that leg's, both sides of the spot are seen, and the plane is read."""
    tr = track_of_pass(35.0, 0.0, headings=(-14.0, 76.0), seed=8, beside=beside)
    plane = estimate_plane(tr.surface_points(), SPOT)
    assert plane.ok, plane.refusal
    est = plane.along(0.0)
    assert est.plane_slope_deg == pytest.approx(35.0, abs=3 * est.plane_sigma_deg)
    assert abs((est.fall_azimuth_deg + 180.0) % 360.0 - 180.0) < 3.0
