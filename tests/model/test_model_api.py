"""The three entry points agree, and bad conditions are refused by name."""

import dataclasses

import numpy as np
import pytest

from slopelander.model import (
    ConditionError,
    LandingConditions,
    Outcome,
    condition_grid,
    simulate,
    simulate_batch,
)
from slopelander.model.stepper import Stepper


def test_batch_matches_single_landings(model):
    grid = condition_grid(
        slope_deg=[0.0, 25.0, 45.0], speed=[1.0, 2.5], tau_up=1.1, tau_down=2.3, reverse_percent=[0.0, 100.0]
    )
    res = simulate_batch(grid, model)
    assert len(res) == 12
    for row, cond in zip(res, grid, strict=True):
        c = LandingConditions(**{n: float(cond[n]) for n in grid.dtype.names})
        single = simulate(c, model, full_horizon=False).result
        assert Outcome(int(row["outcome"])) == single.outcome
        assert row["compression_up"] == pytest.approx(single.compression_up, abs=1e-12)
        assert row["slide"] == pytest.approx(single.slide, abs=1e-12)


def test_recording_to_the_horizon_does_not_change_the_outcome(model):
    c = LandingConditions(slope_deg=15.0, speed=2.0)
    full = simulate(c, model, full_horizon=True)
    short = simulate(c, model, full_horizon=False)
    assert full.result == short.result
    assert full.t[-1] == pytest.approx(model.criteria.horizon, abs=0.01)
    assert np.all(np.diff(full.t) == pytest.approx(0.005))


def test_a_slide_is_recorded_to_the_horizon_still_sliding(model):
    """A landing that slides past the slide criterion (the outcome is decided there) is
    recorded on to the horizon, moving: a recording cut at the decision held the vehicle still
    mid-slide, and a fit then compared sliding drops with a model frozen 24 cm short (a 42.9 deg
    drop, 0.6 s after contact)."""
    c = LandingConditions(slope_deg=42.9, speed=2.79, tau_up=1.1, tau_down=2.3)
    model = model.without("downhill_torque_growth", "downhill_friction_growth")  # (with: it flips)
    full = simulate(c, model, full_horizon=True)
    short = simulate(c, model, full_horizon=False)
    assert dataclasses.astuple(full.result) == pytest.approx(dataclasses.astuple(short.result), nan_ok=True)
    assert full.result.outcome == Outcome.SLID
    assert full.t[-1] == pytest.approx(model.criteria.horizon, abs=0.01)
    assert short.t[-1] < 1.0  # decided mid-slide
    after = full.t > short.t[-1] + 0.1
    assert np.all(np.diff(full.states[after, 0]) > 0), "the vehicle stopped in the recording"


def test_stepper_lands_like_simulate(model):
    """The stepper, started at the same impact state, follows the same trajectory."""
    c = LandingConditions(slope_deg=20.0, speed=2.0, tau_up=1.7, tau_down=1.7)
    tr = simulate(c, model, full_horizon=True)
    s = Stepper(model, slope_deg=20.0)
    s.set_friction(1.7, 1.7)
    s.place(height=0.0, vz=-2.0)
    for _ in range(round(0.3 / model.dt)):
        s.step(model.dt, 0.0, 0.0)
    i = int(np.argmin(np.abs(tr.t - s.t)))
    assert tr.t[i] == pytest.approx(s.t, abs=1e-9)
    b = s.body()
    np.testing.assert_allclose([b.x, b.z, b.pitch], tr.states[i, :3], atol=1e-9)


@pytest.mark.parametrize(
    "kw, field",
    [
        (dict(slope_deg=95.0), "slope_deg"),
        (dict(speed=-1.0), "speed"),
        (dict(tau_up=-0.5), "tau_up"),
        (dict(angle_up_deg=40.0), "angle_up_deg"),
        (dict(reverse_percent=150.0), "reverse_percent"),
        (dict(pitch_deg=float("nan")), "pitch_deg"),
    ],
)
def test_bad_conditions_are_named(model, kw, field):
    with pytest.raises(ConditionError) as err:
        simulate(LandingConditions(**kw), model)
    assert err.value.field == field
    grid = condition_grid(**{k: [v] for k, v in kw.items()}) if field != "pitch_deg" else None
    if grid is not None:
        with pytest.raises(ConditionError) as err:
            simulate_batch(grid, model)
        assert err.value.field == field


def test_rigid_gear_never_compresses(model):
    cond = LandingConditions(slope_deg=10.0, speed=2.5)
    rigid, fsa = simulate(cond, model.rigid()), simulate(cond, model)
    # the joints and legs themselves: locked at their set angle through the whole landing ...
    assert np.ptp(rigid.joint_angles, axis=0).max() < 1e-9
    assert np.ptp(rigid.leg_angles, axis=0).max() < 1e-9
    # ... while the same landing on FSA legs turns them (so the checks above can fail)
    assert np.ptp(fsa.joint_angles, axis=0).max() > np.radians(5.0)
    assert rigid.result.compression_up == 0.0 and rigid.result.compression_down == 0.0
    # 2.5 m/s is far beyond what the stock gear survives (its load limit: about 1.4 m/s level)
    assert rigid.result.outcome == Outcome.DAMAGED
    gentle = simulate(LandingConditions(slope_deg=5.0, speed=0.7), model.rigid())
    assert gentle.result.outcome == Outcome.IDEAL


def test_empty_batch(model):
    assert len(simulate_batch([], model)) == 0
