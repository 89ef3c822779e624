"""The stock rigid gear: its own rebounding skid contact and its structural limit."""

import numpy as np
import pytest

from slopelander.model import LandingConditions, Outcome, simulate
from slopelander.model import kernel as k
from slopelander.model.reference import ReferenceLanding


def _first_contact(tr):
    """Duration (s) of the first ground contact of a level drop and the rebound's restitution."""
    on = tr.raw[:, k.S_NF : k.S_NF + 2].sum(axis=1) > 0.0
    i0 = int(np.argmax(on))
    i1 = i0 + int(np.argmax(~on[i0:]))
    assert i1 > i0, "the feet never left the ground again"
    return tr.t[i1] - tr.t[i0], tr.raw[i1, k.S_V + 1] / tr.conditions.speed


@pytest.mark.parametrize("speed", [0.5, 1.0, 1.3])
def test_rigid_feet_rebound_in_10_to_30_ms_with_restitution_near_one_half(model, speed):
    # the paper's "fast rebounds of traditional landing gears (10-30 ms)", Sec. I; e = 0.5 assumed
    tr = simulate(LandingConditions(slope_deg=0.0, speed=speed), model.rigid(), sample_rate=2400)
    duration, restitution = _first_contact(tr)
    assert 0.010 <= duration <= 0.030
    assert 0.4 <= restitution <= 0.6


def test_the_fsa_contact_does_not_rebound_where_the_rigid_gear_does(model):
    # the same drop on the FSA's rubber-foot contact (k_g, b_g of Table II): its feet stay down
    # for the 0.2 s after touchdown (the body springs back on its legs' flex, its feet do not)
    tr = simulate(LandingConditions(slope_deg=0.0, speed=1.0), model, sample_rate=2400)
    on = tr.raw[:, k.S_NF : k.S_NF + 2].sum(axis=1) > 0.0
    i0 = int(np.argmax(on))
    assert on[i0 : i0 + int(0.2 * 2400)].all()


def test_load_limit_is_the_level_landing_at_half_the_fsa_speed(model):
    # rigid_load_limit is derived: the peak foot load of a level landing at 2.75 / 2 m/s
    peak = {}
    for v in (1.3, 1.375, 1.45):
        tr = simulate(LandingConditions(slope_deg=0.0, speed=v), model.rigid(), full_horizon=False)
        peak[v] = tr.raw[-1, k.S_NPEAK]
        assert tr.result.outcome == (Outcome.IDEAL if v < 1.375 else Outcome.DAMAGED)
    assert peak[1.375] == pytest.approx(model.params["rigid_load_limit"], rel=0.01)


def test_fsa_landings_are_never_damaged(model):
    # the structural limit belongs to the stock gear: the FSA's legs have their own end of travel
    res = simulate(LandingConditions(slope_deg=0.0, speed=3.0), model, full_horizon=False)
    assert res.raw[-1, k.S_NPEAK] > model.params["rigid_load_limit"]
    assert res.result.outcome != Outcome.DAMAGED


def test_the_downhill_foot_of_a_slope_landing_takes_more_than_a_level_one(model):
    # on a slope the uphill foot lands first and the vehicle pivots onto its downhill foot: at
    # 0.5 m/s onto 20 deg that foot is loaded beyond the limit, which a level 0.5 m/s drop is not
    rigid = model.rigid()
    level = simulate(LandingConditions(slope_deg=0.0, speed=0.5), rigid, full_horizon=False)
    steep = simulate(LandingConditions(slope_deg=20.0, speed=0.5), rigid, full_horizon=False)
    assert level.result.outcome == Outcome.IDEAL
    assert steep.result.outcome == Outcome.DAMAGED
    assert steep.raw[-1, k.S_NPEAK] > 2.5 * level.raw[-1, k.S_NPEAK]


@pytest.mark.parametrize(
    "cond",
    [
        LandingConditions(slope_deg=0.0, speed=1.0),
        LandingConditions(slope_deg=10.0, speed=0.5),
        LandingConditions(slope_deg=20.0, speed=1.0),
        LandingConditions(slope_deg=8.0, speed=1.2, reverse_percent=100.0),
    ],
    ids=["level-1ms", "10deg", "20deg-damaged", "8deg-rvt"],
)
def test_rigid_contact_kernel_agrees_with_solve_ivp(model, cond):
    rigid = model.rigid()
    tr = simulate(cond, rigid, full_horizon=False)
    kr = tr.result
    ref = ReferenceLanding(rigid, cond)
    ts, ys, _ = ref.run(kr.t_end)
    rr = ref.result(ts, ys, settled=kr.outcome.value < Outcome.SLID.value)
    assert ref.events > 5  # touchdowns, rebounds and stick-slip found as events
    assert rr.outcome == kr.outcome
    assert ref.n_peak == pytest.approx(tr.raw[-1, k.S_NPEAK], rel=0.03)
    assert rr.slide == pytest.approx(kr.slide, abs=0.01)
    assert rr.min_pitch_deg == pytest.approx(kr.min_pitch_deg, abs=0.5)
    assert rr.final_pitch_deg == pytest.approx(kr.final_pitch_deg, abs=0.5)
