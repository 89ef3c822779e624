"""Why a vehicle at rest under reverse thrust slides once the thrust ends, and what holds it.

Landing 9 of the outdoor campaign, flown on the model alone: 42 deg roof, 2.25 m/s, the table's
preset (1.1/1.7 N*m, uphill legs at 22.3 deg), 100 % reverse thrust from impact until the body
has read still for 0.2 s. Physics only, deterministic: no processes, no clocks.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from model_helpers import ROOF

from slopelander.model import LandingConditions, Model
from slopelander.model.thrust_end import ThrustEnd, land_and_end_thrust

#: its tests share one pair of landings (ramped_end, step_end): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("model/model_thrust_end")

UP, DOWN = 0, 1


@pytest.fixture(scope="module")
def step_end():
    return land_and_end_thrust(ROOF, ThrustEnd(ramp_s=0.0))


@pytest.fixture(scope="module")
def ramped_end():
    return land_and_end_thrust(ROOF, ThrustEnd(ramp_s=1.0))


def test_the_vehicle_is_at_rest_when_the_thrust_ends(step_end):
    assert 0.5 <= step_end.ended_at < 1.0
    assert step_end.speed[0] < 0.05
    # under thrust the feet carry the weight's normal share and the thrust: twice the weight's
    m = Model.default().params
    weight = (m["body_mass"] + 2 * m["leg_mass"]) * m["gravity"]
    assert step_end.normal[0].sum() > 2.0 * weight * math.cos(math.radians(ROOF.slope_deg))


def test_when_the_thrust_steps_off_the_legs_unbend_and_the_uphill_foot_breaks_away_first(step_end):
    r = step_end
    # the friction joints are stuck throughout: the joint angles do not move by a bit
    assert np.array_equal(r.joint_deg[0], r.joint_deg[-1])
    # ...but the legs, bent by twice the weight under thrust, spring back by about 2 deg each
    assert np.all(r.leg_deg[-1] - r.leg_deg[0] > 1.5)
    # the uphill foot: splayed outward under thrust, its friction pointed downhill (>= 0); the
    # legs closing push it downhill, so its friction turns to point uphill while its normal load
    # falls: it reaches the static limit and slips first, within 0.1 s
    assert r.tangential[0, UP] > 0.0
    up_slip, down_slip = r.first_slip()
    assert up_slip < 0.1
    assert r.tangential[int(np.flatnonzero(r.sliding[:, UP])[0]) - 1, UP] < 0.0
    # the downhill foot then carries what the sliding uphill foot (mu_k) no longer holds, as the
    # body rebounds off the surface, and breaks away next
    assert up_slip < down_slip < 0.2
    assert r.height.max() - r.height[0] > 0.005
    # once both slide, kinetic friction (mu_k 0.8 < tan 42 deg) cannot stop it
    assert r.slide > 0.3 and not r.held()


def test_the_uphill_foot_needs_the_static_limit_while_the_downhill_one_has_plenty_left(step_end):
    # read off the forces, not the slip flags: when the uphill foot first needs 0.98 mu_s of
    # its normal force, the downhill foot needs less than half of mu_s (it is being unloaded
    # of its holding share by the same closing of the legs)
    d = step_end.demand()
    i = int(np.flatnonzero(d[:, UP] > 0.98 * step_end.mu_static)[0])
    assert step_end.t[i] < 0.1
    assert d[i, DOWN] < 0.5 * step_end.mu_static


def test_a_ramped_end_lets_the_legs_unbend_slowly_and_the_vehicle_holds(ramped_end, step_end):
    r = ramped_end
    assert r.ended_at == step_end.ended_at  # the same landing up to the end of the thrust
    # the legs end up where they do after the step, the joints still stuck
    assert np.allclose(r.leg_deg[-1], step_end.leg_deg[-1], atol=0.2)
    assert np.array_equal(r.joint_deg[0], r.joint_deg[-1])
    # the uphill foot still gives way, a little, but the downhill foot never needs mu_s
    assert not math.isnan(r.first_slip()[UP])
    assert math.isnan(r.first_slip()[DOWN])
    assert r.demand()[:, DOWN].max() < r.mu_static
    assert r.held() and abs(r.slide) < 0.01
    # at rest without thrust the feet carry the weight's normal share and hold the slope load
    m = Model.default().params
    weight = (m["body_mass"] + 2 * m["leg_mass"]) * m["gravity"]
    a = math.radians(ROOF.slope_deg)
    assert r.normal[-1].sum() == pytest.approx(weight * math.cos(a), rel=0.02)
    assert -r.tangential[-1].sum() == pytest.approx(weight * math.sin(a), rel=0.02)


def test_thrust_end_refuses_nonsense():
    with pytest.raises(ValueError, match="ramp_s"):
        ThrustEnd(ramp_s=-1.0)
    with pytest.raises(ValueError, match="max_s"):
        ThrustEnd(min_s=2.0, max_s=1.0)
    with pytest.raises(ValueError, match="reverse_percent"):
        land_and_end_thrust(LandingConditions(slope_deg=42.0, reverse_percent=0.0))
