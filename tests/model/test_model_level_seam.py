"""No seam at 0 deg: eq. 3 and 4 act on the leg whose foot is pushed outward, not on "the
downhill leg", so a landing on 0.01 deg is the landing on 0 deg (a map has no seam there)."""

import pytest

from slopelander.model import LandingConditions, simulate


@pytest.mark.parametrize("tau", [1.1, 2.3])
def test_peak_compressions_are_continuous_through_level(model, tau):
    """Before, 0 deg gave 0.67/0.67 and 0.01 deg 0.69/0.58 at 2.3 N*m: on level ground eq. 3 was
    off for both legs, on any slope on for one. The bound 0.035 is the default step's own
    spread on these near-level landings (a 10x finer step: 0.655 at 0 deg, 0.642 at 0.01)."""
    res = {
        a: simulate(LandingConditions(slope_deg=a, speed=3.0, tau_up=tau, tau_down=tau), model).result
        for a in (0.0, 0.01, -0.01, 0.1, -0.1)
    }
    level = res[0.0]
    for a, r in res.items():
        assert abs(r.compression_up - r.compression_down) < 0.015, a  # both legs alike
        assert r.compression_up == pytest.approx(level.compression_up, abs=0.035), a
        assert r.compression_down == pytest.approx(level.compression_down, abs=0.035), a
        assert r.outcome == level.outcome


def test_eq3_acts_on_both_legs_on_level_ground(model):
    """Both feet splay outward on level ground, so both joints get the torque growth: switching
    eq. 3 off changes the level landing (it did not, before)."""
    c = LandingConditions(slope_deg=0.0, speed=3.0, tau_up=2.3, tau_down=2.3)
    on = simulate(c, model).result
    off = simulate(c, model.without("downhill_torque_growth")).result
    assert off.compression_up - on.compression_up > 0.01
    assert off.compression_down - on.compression_down > 0.01
