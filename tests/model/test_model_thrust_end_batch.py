"""The batch model with a reverse thrust that ends: judged after the thrust, as flown.

Landing 9 of the outdoor campaign (42 deg roof, 2.25 m/s, the table's preset) with its reverse
thrust ended where the companion's rule ends it on the model alone (``thrust_end``: still for
0.2 s, at least 0.5 s): a step lets it slide, a 1 s ramp holds it. ``simulate`` and
``simulate_batch`` given that duration must say the same as the step-by-step run.
Physics only, deterministic: no processes, no clocks.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from model_helpers import ROOF

from slopelander.model import (
    ConditionError,
    LandingConditions,
    Outcome,
    condition_grid,
    conditions_array,
    default_conditions,
    simulate,
    simulate_batch,
)
from slopelander.model.thrust_end import ThrustEnd, land_and_end_thrust

#: its tests share one batch of landings (flown): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("model/model_thrust_end_batch")


@pytest.fixture(scope="module", params=[0.0, 1.0], ids=["step", "ramp-1s"])
def flown(request):
    """The step-by-step landing, and the batch model's conditions for the same thrust."""
    ramp = request.param
    after = land_and_end_thrust(ROOF, ThrustEnd(ramp_s=ramp))
    cond = replace(ROOF, reverse_duration=after.ended_at - ROOF.reverse_delay, reverse_ramp=ramp)
    return ramp, after, cond


def test_held_to_the_horizon_is_the_default_and_judges_under_the_thrust():
    c = LandingConditions()
    assert c.reverse_duration == math.inf and c.reverse_ramp == 0.0
    assert not ROOF.thrust_ends and ROOF.thrust_off_time == 0.0
    # held, the 42 deg roof lands: the thrust presses the vehicle onto it to the end
    r = simulate(ROOF, full_horizon=False).result
    assert r.outcome.success and r.settle_time < 1.0


def test_the_batch_model_and_the_stepper_agree_on_the_ended_thrust(flown):
    ramp, after, cond = flown
    r = simulate(cond, full_horizon=False).result
    assert cond.thrust_ends and cond.thrust_off_time == pytest.approx(after.ended_at + ramp)
    # the slide under the thrust (before it ends) plus what the stepper saw after it ends
    under = simulate(ROOF, full_horizon=False).result.slide
    if ramp == 0.0:
        assert not after.held()
        assert r.outcome == Outcome.SLID  # still moving 2 s after the thrust is gone
        assert r.t_end == pytest.approx(cond.thrust_off_time + 2.0, abs=0.01)
        assert after.slide > 0.3
        assert r.slide - under == pytest.approx(after.slide, abs=0.05)
    else:
        assert after.held()
        assert r.outcome.success
        assert abs(r.slide - under) < 0.02
        # judged only once the thrust is gone: at rest from the ramp's end, not under it
        assert r.settle_time >= cond.thrust_off_time - 1e-9
    # the batch path runs the same kernel: the same numbers
    b = simulate_batch([cond])[0]
    assert int(b["outcome"]) == r.outcome
    assert b["slide"] == pytest.approx(r.slide, abs=1e-9)


def test_a_thrust_that_ends_takes_the_thrust_off_the_recorded_rotors():
    cond = replace(ROOF, reverse_duration=0.6, reverse_ramp=0.4)
    tr = simulate(cond)
    t = tr.t - tr.t[0]
    thrust = tr.thrust.sum(axis=1)
    assert thrust[(t > 0.4) & (t < 0.6)].max() < -10.0  # full reverse (pulls toward the roof)
    # halfway down the ramp the command is half: a quarter of the thrust (w^2), a little more
    # as the rotor speed lags the falling command by its time constant
    full = thrust[(t > 0.4) & (t < 0.6)].mean()
    mid = thrust[(t > 0.78) & (t < 0.82)].mean()
    assert 0.25 * full > mid > 0.5 * full
    assert np.abs(thrust[t > 1.2]).max() < 0.1
    assert t[-1] >= cond.thrust_off_time + 2.0 - 0.01  # the recording covers the later horizon


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("reverse_duration", 0.0, "reverse_percent 0"),
        ("reverse_duration", -1.0, "0..30"),
        ("reverse_duration", math.nan, "must be a number"),
        ("reverse_duration", 31.0, "0..30"),
        ("reverse_duration", -math.inf, "0..30"),
        ("reverse_ramp", -0.1, "0..10"),
        ("reverse_ramp", math.inf, "finite"),
        ("reverse_ramp", 11.0, "0..10"),
    ],
)
def test_bad_thrust_ends_are_refused_by_name(field, value, match):
    c = replace(ROOF, **{"reverse_duration": 1.0, field: value})
    with pytest.raises(ConditionError, match=match) as e:
        c.validate()
    assert e.value.field == field
    with pytest.raises(ConditionError, match=field):
        simulate(c)


def test_a_ramp_on_a_held_thrust_is_refused():
    with pytest.raises(ConditionError, match="ramp needs a finite reverse_duration"):
        simulate(replace(ROOF, reverse_ramp=1.0))


def test_batch_rows_are_checked_and_a_zero_filled_array_is_not_a_silent_zero_duration():
    ok = condition_grid(slope_deg=[10.0, 20.0], reverse_percent=100.0, reverse_duration=[0.5, np.inf])
    assert np.isinf(conditions_array(ok)["reverse_duration"]).sum() == 2
    zeros = np.zeros(2, dtype=ok.dtype)  # filled as a sweep fills its axes, the rest left 0
    for name in ("speed", "tau_up", "tau_down", "angle_up_deg", "angle_down_deg", "reverse_percent"):
        zeros[name] = ok[name][:2]
    with pytest.raises(ConditionError, match="reverse_duration"):
        simulate_batch(zeros)
    assert (default_conditions(2)["reverse_duration"] == np.inf).all()
    bad = ok.copy()
    bad["reverse_ramp"][1] = 0.5  # a ramp on the held row
    with pytest.raises(ConditionError, match="reverse_ramp"):
        simulate_batch(bad)
    nan = ok.copy()
    nan["reverse_duration"][0] = np.nan
    with pytest.raises(ConditionError, match="non-finite"):
        conditions_array(nan)
    neg = ok.copy()
    neg["speed"][0] = np.inf  # only the duration may be infinite
    with pytest.raises(ConditionError, match="non-finite"):
        conditions_array(neg)
