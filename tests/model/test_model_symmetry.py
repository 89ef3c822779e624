"""Mirror symmetry: a landing on slope -a is the mirror image of the same landing on +a."""

import numpy as np
import pytest

from slopelander.model import LandingConditions, simulate


@pytest.mark.parametrize("rvt", [0.0, 100.0])
def test_negative_slope_mirrors_positive(model, rvt):
    kw = dict(speed=2.2, tau_up=1.1, tau_down=2.3, angle_up_deg=30.0, reverse_percent=rvt)
    a = simulate(
        LandingConditions(slope_deg=30.0, horizontal_speed=0.3, pitch_deg=4.0, pitch_rate_dps=20.0, **kw),
        model,
    )
    b = simulate(
        LandingConditions(slope_deg=-30.0, horizontal_speed=-0.3, pitch_deg=-4.0, pitch_rate_dps=-20.0, **kw),
        model,
    )
    sa, sb = a.states, b.states
    mirror = np.array([-1.0, 1.0, -1.0, -1.0, 1.0, -1.0])
    assert len(sa) == len(sb) > 100
    np.testing.assert_allclose(sa, sb * mirror, atol=1e-9)
    ra, rb = a.result, b.result
    assert ra.outcome == rb.outcome
    for f in ("compression_up", "compression_down", "slide", "final_pitch_deg", "min_pitch_deg"):
        assert getattr(ra, f) == pytest.approx(getattr(rb, f), abs=1e-9), f


def test_level_ground_landing_is_symmetric(model):
    r = simulate(LandingConditions(slope_deg=0.0, speed=3.0, tau_up=2.3, tau_down=2.3), model).result
    assert r.compression_up == pytest.approx(r.compression_down, abs=1e-12)
    assert r.compression_up > 0.4
