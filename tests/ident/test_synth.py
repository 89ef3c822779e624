"""Synthetic drops: the truth underneath, and noise shaped like motion capture."""

import math

import numpy as np
import pytest

from slopelander.ident.synth import (
    PAPER_TORQUE_LEVELS,
    NoiseModel,
    differentiate,
    paper_drops,
    survived,
    synthesize,
    true_states,
)
from slopelander.model import Outcome, simulate


def test_paper_spread_of_drops():
    conds = paper_drops(10, seed=0)
    slopes = [c.slope_deg for c in conds]
    speeds = [c.speed for c in conds]
    assert 0 <= min(slopes) < 5 and 40 < max(slopes) <= 45
    assert 1 <= min(speeds) < 1.3 and 2.7 < max(speeds) <= 3
    assert all(c.tau_up in PAPER_TORQUE_LEVELS and c.tau_down in PAPER_TORQUE_LEVELS for c in conds)


def test_a_part_of_the_paper_spread():
    conds = paper_drops(8, seed=0, slopes=(30.0, 45.0), speeds=(1.0, 2.0))
    slopes = sorted(c.slope_deg for c in conds)
    assert 30 <= slopes[0] < 32 and 43 < slopes[-1] <= 45
    assert all(1.0 <= c.speed <= 2.0 for c in conds)
    for bad in ({"slopes": (30.0, 50.0)}, {"slopes": (20.0, 10.0)}, {"speeds": (0.5, 3.0)}):
        with pytest.raises(ValueError, match="within the paper's"):
            paper_drops(4, **bad)


def test_survived_keeps_the_drops_that_do_not_flip(model):
    conds = paper_drops(10, seed=0)
    kept = survived(model, conds)
    outcomes = [simulate(c, model).result.outcome for c in conds]
    assert kept == [c for c, o in zip(conds, outcomes, strict=True) if o is not Outcome.FLIP]
    assert 0 < len(kept) < len(conds)


def test_some_paper_drops_flip(model):
    drops = synthesize(model, paper_drops(10, seed=0), NoiseModel.none(), duration=0.3)
    outcomes = [d.outcome for d in drops]
    assert Outcome.FLIP in outcomes and any(o.success for o in outcomes)


def test_noiseless_synthesis_is_the_simulation(model):
    cond = paper_drops(3, seed=1)[1]
    d = synthesize(model, [cond], NoiseModel.none(), duration=0.5)[0]
    tr = simulate(cond, model, sample_rate=200.0)
    after = d.t >= 0
    np.testing.assert_allclose(d.states[after], tr.states[: after.sum()], atol=1e-9)
    # before contact: free fall that ends in the impact state
    before = d.states[~after]
    np.testing.assert_allclose(before[-1, 4], -cond.speed - 9.81 * d.t[~after][-1], rtol=1e-9)


def test_noise_has_the_stated_size_and_rates_come_from_noisy_positions(model):
    conds = paper_drops(4, seed=2)
    noise = NoiseModel(position_sd=1e-3, angle_sd_deg=0.3, latency=0.005)
    drops = synthesize(model, conds, noise, seed=5, duration=0.5)
    err_pos, err_ang = [], []
    for d in drops:
        truth, _ = true_states(model, d.conditions, d.t - noise.latency)
        err_pos.append(d.states[:, :2] - truth[:, :2])
        err_ang.append(d.states[:, 2] - truth[:, 2])
        # inside, the 7-frame slope of the recorded positions; the first and last three rates are
        # centred on frames beyond the recording (as a lab's take runs on beyond its export)
        np.testing.assert_allclose(d.states[3:-3, 3:], differentiate(d.states[:, :3], d.t, 7)[3:-3])
    sd_pos = np.concatenate(err_pos).std()
    sd_ang = math.degrees(np.concatenate(err_ang).std())
    assert 0.85e-3 < sd_pos < 1.15e-3
    assert 0.25 < sd_ang < 0.35


def test_the_differentiator_is_exact_on_a_parabola_and_quiets_noise():
    t = np.arange(0, 0.5, 0.005)
    x = np.column_stack([3 * t**2 - t, np.sin(0 * t)])
    np.testing.assert_allclose(differentiate(x, t, 7)[3:-3, 0], 6 * t[3:-3] - 1, atol=1e-9)
    noise = np.random.default_rng(0).normal(0, 1e-3, (20000, 1))
    tt = np.arange(20000) * 0.005
    ratio = differentiate(noise, tt, 7)[3:-3].std() / np.gradient(noise[:, 0], tt).std()
    assert 0.2 < ratio < 0.35  # sqrt(1/28) / (sqrt(1/2)) = 0.27


def test_latency_delays_the_recording(model):
    cond = paper_drops(2, seed=0)[0]
    late = synthesize(model, [cond], NoiseModel(0, 0, 0.01), duration=0.3)[0]
    truth, _ = true_states(model, cond, late.t - 0.01)
    np.testing.assert_allclose(late.states[:, :3], truth[:, :3], atol=1e-12)
    ontime, _ = true_states(model, cond, late.t)
    assert np.abs(late.states[:, 1] - ontime[:, 1]).max() > 0.005


def test_seeds_differ_and_repeat(model):
    cond = paper_drops(1, seed=0)
    a = synthesize(model, cond, seed=1, duration=0.2)[0].states
    b = synthesize(model, cond, seed=1, duration=0.2)[0].states
    c = synthesize(model, cond, seed=2, duration=0.2)[0].states
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
