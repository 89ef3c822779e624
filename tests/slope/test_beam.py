"""The simulated rangefinder's beam over the world: what a real one has (beam width, a lost return
over an edge, the ridge and the gutter), identical to the physics' plane where the footprint lies
on the roof alone (every landing reads what it read before)."""

from __future__ import annotations

import math

import pytest

from slopelander_sitl.vehicle.scenario import ScenarioError, scenario_from_dict
from slopelander_sitl.vehicle.world import beam_range, start_on_ground, world_beam


def over(x: float, height: float = 2.0, **scn):
    s = scenario_from_dict({"slope_deg": 35.0, **scn})
    stepper, world = start_on_ground(s)
    stepper.place(height=height, x=x - world.ox)
    return stepper, world


def test_on_the_roof_the_beam_reads_the_physics_plane() -> None:
    s = scenario_from_dict({"slope_deg": 35.0, "start_on": "roof", "start_x": 5.5})
    stepper, world = start_on_ground(s)
    stepper.place(height=2.0, x=5.5 - world.ox)
    assert world_beam(stepper, world) == pytest.approx(beam_range(stepper), rel=2e-4)


def test_over_the_step_edge_the_return_is_lost() -> None:
    stepper, world = over(2.99)
    assert math.isnan(world_beam(stepper, world))
    stepper, world = over(2.5)
    assert world_beam(stepper, world) == pytest.approx(2.0 + 0.148, abs=0.01)


def test_a_gable_ridge_is_read_without_a_loss() -> None:
    stepper, world = over(2.99, ridge="gable")
    r = world_beam(stepper, world)
    assert math.isfinite(r) and r < beam_range(stepper)  # the ridge is above the pad


def test_beyond_the_gutter_nothing_is_in_range() -> None:
    s = scenario_from_dict({"slope_deg": 35.0, "start_on": "roof", "start_x": 4.0, "roof_length": 2.0})
    stepper, world = start_on_ground(s)
    stepper.place(height=2.0, x=6.0 - world.ox)
    assert math.isinf(world_beam(stepper, world))  # the gutter is at x = 5 m
    stepper.place(height=2.0, x=5.0 - world.ox)
    assert math.isnan(world_beam(stepper, world))  # the footprint straddles the gutter
    stepper.place(height=2.0, x=4.5 - world.ox)
    assert world_beam(stepper, world) == pytest.approx(beam_range(stepper), rel=2e-4)


def test_a_sonar_reads_the_nearest_return_a_lidar_the_mean() -> None:
    base = {"slope_deg": 45.0, "start_on": "roof", "start_x": 5.5}
    got = {}
    for mode in ("mean", "nearest"):
        s = scenario_from_dict(
            {**base, "rangefinder": {"beam_deg": 20.0, "return": mode, "edge_dropout_m": 5}}
        )
        stepper, world = start_on_ground(s)
        stepper.place(height=2.0, x=5.5 - world.ox)
        got[mode] = world_beam(stepper, world)
    axis = beam_range(stepper)
    assert got["nearest"] < axis < got["mean"]


@pytest.mark.parametrize(
    "bad",
    [
        {"ridge": "hip"},
        {"roof_length": 0.1},
        {"rangefinder": {"return": "max"}},
        {"rangefinder": {"width": 2}},
        {"fall_azimuth_deg": "east"},
        {"fall_azimuth_deg": 400},
        {"fall_azimuth_deg": 90, "ridge": "gable"},
    ],
)
def test_bad_beam_and_roof_keys_are_named(bad) -> None:
    with pytest.raises(ScenarioError, match=next(iter(bad))):
        scenario_from_dict(bad)


def airborne(scn: dict, north: float, height: float = 2.0):
    """The model and its world with the body ``height`` m over the pad's level at ``north``,
    stepped once at hover (so that the world hands the physics the surface under it)."""
    stepper, world = start_on_ground(scenario_from_dict({"slope_deg": 45.0, **scn}))
    stepper.place(height=height, x=north - world.ox)
    u = stepper.hover_command()
    stepper.step(0.001, u, u)
    world.update(stepper)
    return stepper, world


def test_a_roof_falling_east_is_level_along_north_and_its_full_slope_facing_east() -> None:
    """``fall_azimuth_deg: 90``: along north (the way from the pad) the roof's section is level, so
    the beam reads the same range all along it; turned east the section is the roof's 45 deg,
    and the beam along it reads the physics' plane there."""
    stepper, world = airborne({"fall_azimuth_deg": 90.0}, 5.0)
    assert world.on_roof and stepper.slope_deg == pytest.approx(0.0, abs=1e-9)
    ranges = []
    for north in (4.0, 5.0, 6.0):
        stepper.place(height=2.0, x=north - world.ox)
        ranges.append(world_beam(stepper, world))
    assert max(ranges) - min(ranges) < 1e-9, ranges
    stepper.place(height=2.0, x=5.0 - world.ox)
    ne = world.ne(stepper.body().x + world.ox)
    assert world.turn(stepper, 90.0)
    assert world.ne(stepper.body().x + world.ox) == pytest.approx(ne)  # turned on the spot
    assert stepper.slope_deg == pytest.approx(45.0)
    assert world_beam(stepper, world) == pytest.approx(beam_range(stepper), rel=5e-4)  # 2 deg beam: its mean
    # one metre east the roof is a metre lower: at the same height the range grows by that
    r0, z0 = world_beam(stepper, world), stepper.body().z
    stepper.place(height=1.0, x=stepper.body().x + 1.0)
    assert world_beam(stepper, world) == pytest.approx(r0 + 1.0 + stepper.body().z - z0, rel=1e-3)


@pytest.mark.parametrize("heading", [0.0, 30.0, 135.0, 250.0])
def test_any_heading_sees_the_roofs_section(heading: float) -> None:
    """Turned to any heading over a roof falling toward 60 deg, the beam reads the roof's plane
    below the body (vertical, from its height over the plane) and the physics is handed the
    section, atan(tan(slope) cos(heading - fall)), level where it falls toward the back."""
    stepper, world = airborne({"fall_azimuth_deg": 60.0}, 5.5, height=2.5)
    assert world.turn(stepper, heading)
    b = stepper.body()
    n, e = world.ne(b.x + world.ox)
    over = b.z + world.oz - world.roof_height(n, e)
    section = math.degrees(math.atan(math.tan(math.radians(45.0)) * math.cos(math.radians(heading - 60.0))))
    assert stepper.slope_deg == pytest.approx(max(0.0, section), abs=1e-9)
    assert world_beam(stepper, world) == pytest.approx(over, rel=2e-3)


def test_the_heading_does_not_turn_on_the_ground_or_close_over_it() -> None:
    """In contact (the feet hold it) or with the body origin within 0.35 m of the surface the
    heading stays, and the world is unchanged."""
    s = scenario_from_dict({"slope_deg": 45.0, "fall_azimuth_deg": 90.0, "start_on": "roof", "start_x": 5.5})
    stepper, world = start_on_ground(s)
    assert stepper.in_contact()
    before = (world.heading_deg, world.n0, world.e0, world.ox, world.oz)
    assert not world.turn(stepper, 90.0)
    assert (world.heading_deg, world.n0, world.e0, world.ox, world.oz) == before
    stepper, world = airborne({"fall_azimuth_deg": 90.0}, 5.5, height=0.1)
    assert not world.turn(stepper, 90.0) and world.heading_deg == 0.0
