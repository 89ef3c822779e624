"""A steady force on the body (how the simulated vehicle feels a wind gust) moves it as F = m a."""

import math

import pytest

from slopelander.model.conditions import ConditionError
from slopelander.model.stepper import Stepper


def test_a_horizontal_force_accelerates_the_falling_vehicle_by_f_over_m() -> None:
    s = Stepper(slope_deg=0.0)
    s.place(height=5.0)
    p = s.model.params
    mass = p["body_mass"] + 2 * p["leg_mass"]
    s.set_external_force(fx=3.0)
    s.step(0.2, 0.0, 0.0)
    b = s.body()
    assert b.vx == pytest.approx(3.0 / mass * 0.2, rel=0.02)
    assert b.vz == pytest.approx(-p["gravity"] * 0.2, rel=0.02)


def test_removing_the_force_stops_the_acceleration() -> None:
    s = Stepper(slope_deg=0.0)
    s.place(height=5.0)
    s.set_external_force(fx=3.0)
    s.step(0.1, 0.0, 0.0)
    s.set_external_force()
    v = s.body().vx
    s.step(0.1, 0.0, 0.0)
    assert s.body().vx == pytest.approx(v, abs=1e-6)


@pytest.mark.parametrize("bad", [math.nan, 1e6])
def test_an_absurd_force_is_refused(bad: float) -> None:
    with pytest.raises(ConditionError):
        Stepper().set_external_force(fx=bad)
