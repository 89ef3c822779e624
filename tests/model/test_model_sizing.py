"""Sec. III sizing, and what a planar leg stands for (DESIGN.md 3: a real pair)."""

import pytest

from slopelander.model import LandingConditions, Outcome, simulate
from slopelander.model.sizing import required_joint_torque


def test_paper_sizing_needs_3_2_nm_per_joint(model):
    p = model.params
    vehicle = p["body_mass"] + 2 * p["leg_mass"]  # the whole 1.55 kg vehicle
    assert vehicle == pytest.approx(1.55, abs=0.02)
    tau = required_joint_torque(vehicle, 3.0, p["leg_travel_deg"], joints=4, safety=1.2)
    assert tau == pytest.approx(3.2, abs=0.1)


def test_sizing_rejects_nonsense():
    with pytest.raises(ValueError):
        required_joint_torque(-1.0, 3.0, 37.0)


def test_a_planar_leg_is_a_pair_of_real_joints(model):
    """3 m/s on level ground at the paper's highest torque (2.3 N*m per joint): with each
    planar leg standing for two joints the legs absorb it within their travel; with one
    joint per planar leg they run to the end of travel (docs/model.md, what a planar leg stands for)."""
    cond = LandingConditions(slope_deg=0.0, speed=3.0, tau_up=2.3, tau_down=2.3)
    assert model.params["joints_per_planar_leg"] == 2.0
    pair = simulate(cond, model).result
    single = simulate(cond, model.with_params(provenance="assumed", joints_per_planar_leg=1.0)).result
    assert pair.outcome in (Outcome.IDEAL, Outcome.UNDER_USED)
    assert pair.compression_up < 0.9
    assert single.outcome in (Outcome.END_OF_TRAVEL, Outcome.JOINT_TOUCH)
    assert single.compression_up > pair.compression_up
