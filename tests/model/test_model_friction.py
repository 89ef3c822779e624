"""Stiction: feet that hold without creeping up to the static limit, joints that do not creep
below their friction level."""

import math

import pytest
from model_helpers import settle_on_slope, slide_after

from slopelander.model import LandingConditions, kernel, simulate
from slopelander.model.stepper import Stepper


def _static_limit_deg(model):
    return math.degrees(math.atan(model.params["friction_static"]))


def test_rigid_gear_holds_below_the_static_limit_and_slides_above(model):
    rigid = model.rigid()
    limit = _static_limit_deg(rigid)  # 50.2 deg for mu_s = 1.2
    # 3 deg of margin: near the limit the uphill skid carries a tenth of the weight and slides at
    # mu_k, so the downhill one holds the rest alone; on its lightly damped contact the jolt of
    # the uphill skid re-sticking breaks it loose from 48.2 deg (it holds at 48.0 deg)
    assert slide_after(settle_on_slope(rigid, limit - 3.0), 2.0) == pytest.approx(0.0, abs=1e-4)
    assert slide_after(settle_on_slope(rigid, limit + 2.0), 2.0) > 0.5


def test_fsa_vehicle_at_rest_does_not_creep(model):
    """Hinged legs splay as they load, so the feet of the FSA vehicle settle near the kinetic
    limit; below atan(mu_k) it must stay put, not creep (docs/model.md)."""
    angle = math.degrees(math.atan(model.params["friction_kinetic"])) - 3.0
    s = settle_on_slope(model, angle)
    slide_after(s, 0.5)  # the feet finish settling under the real friction
    assert slide_after(s, 2.0) == pytest.approx(0.0, abs=1e-5)


def test_regularised_friction_creeps_where_stiction_holds(model):
    smooth = model.without("foot_stiction").with_effects("regularised_friction")
    a, b = settle_on_slope(smooth, 30.0), settle_on_slope(model, 30.0)
    slide_after(a, 0.5)  # the feet take up the real friction
    slide_after(b, 0.5)
    creep = slide_after(a, 2.0)
    stuck = slide_after(b, 2.0)
    assert creep > 5e-3
    assert abs(stuck) < 1e-4


def test_joint_below_its_friction_level_does_not_creep(model):
    """Standing on level ground, a joint set well above its static load never moves."""
    s = Stepper(model)
    s.set_friction(1.7, 1.7)
    s.place(height=0.0)
    for _ in range(500):
        s.step(1e-3, 0.0, 0.0)
    q0 = s.joint_angles_deg()
    for _ in range(2000):
        s.step(1e-3, 0.0, 0.0)
    assert s.joint_angles_deg() == q0  # exactly: a stuck joint has no rate at all
    assert s.st[kernel.S_JM] == 0.0 and s.st[kernel.S_JM + 1] == 0.0


def test_joint_below_its_load_slips_until_the_legs_carry_it(model):
    s = Stepper(model)
    s.set_friction(0.05, 0.05)
    s.place(height=0.0)
    for _ in range(1500):
        s.step(1e-3, 0.0, 0.0)
    up, down = s.joint_angles_deg()
    assert up < model.params.angle_max_deg - 5.0 and down < model.params.angle_max_deg - 5.0


def test_slipping_joint_applies_exactly_its_friction_torque(model):
    """While a joint slips, the flex torque it passes to the leg is exactly +-tau (Fig. 5),
    so the flex deflection relaxes to tau / k_q."""
    c = LandingConditions(slope_deg=0.0, speed=3.0, tau_up=2.3, tau_down=2.3)
    tr = simulate(c, model.without("downhill_torque_growth"), sample_rate=1000)
    p = model.params
    kq = p["flex_stiffness"] * p["joints_per_planar_leg"]
    tau = 2.3 * p["joints_per_planar_leg"]
    slipping = tr.raw[:, kernel.S_JM] == -1.0
    assert slipping.sum() > 20
    t_slip = tr.t[slipping]
    defl = (tr.joint_angles[:, 0] - tr.leg_angles[:, 0])[slipping]
    # 20 ms into the slip (relaxation time b_q / k_q = 5.2 ms) the deflection sits at tau / k_q
    late = defl[t_slip > t_slip[0] + 0.02]
    assert len(late) > 10
    assert late == pytest.approx(tau / kq, rel=0.02)
