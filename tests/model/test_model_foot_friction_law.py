"""The foot's friction law (velocity weakening) and why the FSA vehicle at rest holds less than
the static friction limit: its legs splay under load (docs/model.md, foot friction)."""

import itertools
import math

import pytest
from model_helpers import settle_on_slope, slide_after

from slopelander.model import LandingConditions, Outcome, kernel, simulate
from slopelander.model.reference import ReferenceLanding


def test_sliding_coefficient_falls_from_static_to_kinetic_with_slip_speed(model):
    p = model.params
    mu_k, mu_s, v_s = p["friction_kinetic"], p["friction_static"], p["stribeck_speed"]
    delta = p["stribeck_exponent"]
    speeds = [0.0, 0.1 * v_s, v_s, 3 * v_s, 100 * v_s]
    mus = [kernel.stribeck(mu_k, mu_s, v, v_s, delta) for v in speeds]
    assert mus[0] == mu_s  # continuous at breakaway: a foot starts slipping at mu_s
    assert mus[2] == pytest.approx(mu_k + (mu_s - mu_k) / math.e)
    assert mus[-1] == pytest.approx(mu_k)
    assert all(a > b for a, b in itertools.pairwise(mus))
    assert kernel.stribeck(mu_k, mu_s, -v_s, v_s, delta) == mus[2]  # either direction
    # eq. 4 may lift the kinetic level above mu_s: the law then never lowers it
    assert kernel.stribeck(1.5, mu_s, 0.0, v_s, delta) == 1.5


def test_a_slowing_foot_sticks_again_below_the_static_limit(model):
    """On 44 deg (above atan mu_k = 38.7 deg) a foot sliding on mu_k never stops; with friction
    that returns to mu_s over a slow enough slip it catches and holds."""
    steep = 44.0
    kinetic = model.without("velocity_weakening_friction")
    weak = model.with_params(provenance="assumed", stribeck_speed=0.1)
    a, b = settle_on_slope(kinetic, steep), settle_on_slope(weak, steep)
    assert slide_after(a, 2.5) > 0.5
    slide_after(b, 0.5)  # the feet settle (half a millimetre)
    assert slide_after(b, 2.0) == pytest.approx(0.0, abs=1e-5)  # and then hold: no creep


def test_legs_splay_under_load_so_the_downhill_foot_needs_more_than_the_slope(model):
    """Why the FSA vehicle at rest slides at 42 deg although tan 42 = 0.90 is far below mu_s = 1.2.

    Set down on 42 deg with sticky feet, the hinged legs bend outward under the weight. The
    uphill foot's pad then holds the uphill leg against that splay: its friction points down
    the slope (+), adding to the load the downhill foot must hold instead of sharing it. The
    downhill foot needs |F_t|/N above mu_s, so it breaks away and the vehicle slides. Legs ten
    times stiffer in bending splay less: the uphill foot helps hold the vehicle, the downhill
    foot needs less than mu_s, and the same vehicle holds.
    """
    slope = 42.0
    mu_s = model.params["friction_static"]
    assert math.tan(math.radians(slope)) < mu_s - 0.25

    def at_rest(m):
        s = settle_on_slope(m, slope)
        n = s.st[kernel.S_NF : kernel.S_NF + 2].copy()
        ft = s.st[kernel.S_FT : kernel.S_FT + 2].copy()  # along the surface, + downhill
        return n, ft, slide_after(s, 2.0)

    (_, n_down), (ft_up, ft_down), slid = at_rest(model)
    assert ft_up > 0.0  # the uphill foot holds its leg's splay, not the vehicle
    assert abs(ft_down) / n_down > mu_s  # more than the foot can hold
    assert slid > 0.05

    stiff = model.with_params(provenance="assumed", flex_stiffness=10 * model.params["flex_stiffness"])
    (_, n_down), (ft_up, ft_down), slid = at_rest(stiff)
    assert ft_up < 0.0  # now the uphill foot helps to hold the vehicle up the slope
    assert abs(ft_down) / n_down < mu_s - 0.1
    assert slid == pytest.approx(0.0, abs=1e-4)


def test_kernel_agrees_with_solve_ivp_where_the_law_decides(model):
    """A slope above atan mu_k with a slow Stribeck fall, so a sliding foot's coefficient changes
    along its slide: the independent integrator sees the same landing."""
    weak = model.with_params(provenance="assumed", stribeck_speed=0.1)
    cond = LandingConditions(slope_deg=40.0, speed=1.0, tau_up=1.1, tau_down=1.7, angle_up_deg=24.0)
    kr = simulate(cond, weak, full_horizon=False).result
    ref = ReferenceLanding(weak, cond)
    ts, ys, _ = ref.run(kr.t_end)
    rr = ref.result(ts, ys, settled=kr.outcome.value < Outcome.SLID.value)
    assert rr.outcome == kr.outcome
    assert rr.compression_up == pytest.approx(kr.compression_up, abs=0.03)
    assert rr.compression_down == pytest.approx(kr.compression_down, abs=0.03)
    assert rr.slide == pytest.approx(kr.slide, abs=0.01)
    assert rr.min_pitch_deg == pytest.approx(kr.min_pitch_deg, abs=0.5)
