"""The simulated rangefinder's beam over the world: what a real one has (beam width, a lost return
over an edge, the ridge and the gutter), identical to the physics' plane where the footprint lies
on the roof alone (every landing reads what it read before)."""

from __future__ import annotations

import math

import pytest

from sitl.vehicle.scenario import ScenarioError, scenario_from_dict
from sitl.vehicle.world import beam_range, start_on_ground, world_beam


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
    ],
)
def test_bad_beam_and_roof_keys_are_named(bad) -> None:
    with pytest.raises(ScenarioError, match=next(iter(bad))):
        scenario_from_dict(bad)
