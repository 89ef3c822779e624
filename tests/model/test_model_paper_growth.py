"""The paper's reading of eqs. 3 and 4 (``paper_downhill_growth``: the downhill leg only) against
the model's (each leg by its physical condition): the same where the two readings must agree,
different where they must not, mirror-symmetric, and the same in the scipy reference."""

import numpy as np
import pytest

from slopelander.model import EffectError, LandingConditions, Model, Outcome, simulate
from slopelander.model.reference import ReferenceLanding

SLOPE = LandingConditions(slope_deg=30.0, speed=2.5, tau_up=1.1, tau_down=1.1)


def test_level_ground_symmetric_landings_are_the_same_in_both_readings(model):
    """On level ground neither leg is downhill: the paper's reading acts by the condition on
    both legs, like the model's, and a symmetric landing comes out the same to the last bit."""
    c = LandingConditions(slope_deg=0.0, speed=3.0, tau_up=1.7, tau_down=1.7)
    a = simulate(c, model)
    b = simulate(c, model.with_effects("paper_downhill_growth"))
    assert np.array_equal(a.raw, b.raw)
    assert a.result.compression_up == pytest.approx(a.result.compression_down, abs=1e-12)


def test_on_a_slope_the_readings_differ_through_the_uphill_leg_alone(model):
    """On 30 deg the uphill leg meets eqs. 3 and 4's conditions too: the model grows its torque
    and friction, the paper's reading does not, so the landings differ; with both factors at
    zero there is nothing to grow and the two are the same again."""
    a = simulate(SLOPE, model)
    b = simulate(SLOPE, model.with_effects("paper_downhill_growth"))
    assert not np.array_equal(a.states, b.states)
    # a weaker uphill joint (no growth) compresses that leg more
    assert b.result.compression_up > a.result.compression_up + 1e-3
    off = dict(factor_tau=0.0, factor_mu=0.0)
    a0 = simulate(SLOPE, model.with_params(**off))
    b0 = simulate(SLOPE, model.with_effects("paper_downhill_growth").with_params(**off))
    assert np.array_equal(a0.raw, b0.raw)


def test_the_paper_reading_is_mirror_symmetric(model):
    """The downhill leg is C on a negative slope, D on a positive one: mirrored landings stay
    mirrored under the paper's reading."""
    m = model.with_effects("paper_downhill_growth")
    kw = dict(speed=2.2, tau_up=1.1, tau_down=2.3, angle_up_deg=30.0)
    a = simulate(LandingConditions(slope_deg=30.0, horizontal_speed=0.3, **kw), m)
    b = simulate(LandingConditions(slope_deg=-30.0, horizontal_speed=-0.3, **kw), m)
    mirror = np.array([-1.0, 1.0, -1.0, -1.0, 1.0, -1.0])
    np.testing.assert_allclose(a.states, b.states * mirror, atol=1e-9)


def test_the_reference_integrator_reads_the_switch_alike(model):
    """The scipy reference applies the same reading: kernel and reference agree under it, as
    they do under the model's (tests/model/test_model_reference.py)."""
    m = model.with_effects("paper_downhill_growth")
    kr = simulate(SLOPE, m, full_horizon=False).result
    ref = ReferenceLanding(m, SLOPE)
    ts, ys, _ = ref.run(kr.t_end)
    rr = ref.result(ts, ys, settled=kr.outcome.value < Outcome.SLID.value)
    assert rr.outcome == kr.outcome
    assert rr.compression_up == pytest.approx(kr.compression_up, abs=0.03)
    assert rr.compression_down == pytest.approx(kr.compression_down, abs=0.03)
    assert rr.slide == pytest.approx(kr.slide, abs=0.01)
    assert rr.min_pitch_deg == pytest.approx(kr.min_pitch_deg, abs=0.5)


def test_the_switch_needs_a_growth_effect_and_the_rigid_gear_drops_it():
    m = Model.default()
    with pytest.raises(EffectError, match="'paper_downhill_growth' says which leg"):
        m.without("downhill_torque_growth", "downhill_friction_growth").with_effects("paper_downhill_growth")
    assert "paper_downhill_growth" not in m.with_effects("paper_downhill_growth").rigid().effects
