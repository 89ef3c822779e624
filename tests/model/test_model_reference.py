"""The compiled kernel against an independent event-driven solve_ivp integration."""

import pytest

from slopelander.model import LandingConditions, Outcome, simulate
from slopelander.model.reference import ReferenceLanding


@pytest.mark.parametrize(
    "cond",
    [
        LandingConditions(slope_deg=20.0, speed=2.5, tau_up=1.1, tau_down=1.7),
        LandingConditions(slope_deg=0.0, speed=3.0, tau_up=2.3, tau_down=2.3),
        LandingConditions(
            slope_deg=35.0, speed=2.0, tau_up=1.1, tau_down=2.3, angle_up_deg=27.0, reverse_percent=100.0
        ),
        LandingConditions(
            slope_deg=35.0,
            speed=2.0,
            tau_up=1.1,
            tau_down=2.3,
            angle_up_deg=27.0,
            reverse_percent=100.0,
            reverse_duration=0.5,
            reverse_ramp=0.3,
        ),
        LandingConditions(
            slope_deg=40.0,
            speed=2.0,
            tau_up=1.1,
            tau_down=1.7,
            angle_up_deg=23.0,
            reverse_percent=100.0,
            reverse_duration=0.5,
        ),
    ],
    ids=["20deg", "level-3ms", "35deg-rvt", "35deg-rvt-ramped-end", "40deg-rvt-step-end"],
)
def test_kernel_agrees_with_solve_ivp(model, cond):
    kr = simulate(cond, model, full_horizon=False).result
    ref = ReferenceLanding(model, cond)
    ts, ys, _ = ref.run(kr.t_end)
    rr = ref.result(ts, ys, settled=kr.outcome.value < Outcome.SLID.value)
    assert ref.events > 5  # contacts, stick-slip and joint slips were all found as events
    assert rr.outcome == kr.outcome
    assert rr.compression_up == pytest.approx(kr.compression_up, abs=0.03)
    assert rr.compression_down == pytest.approx(kr.compression_down, abs=0.03)
    assert rr.slide == pytest.approx(kr.slide, abs=0.01)
    assert rr.min_pitch_deg == pytest.approx(kr.min_pitch_deg, abs=0.5)


def test_reference_refuses_user_effects(model):
    import numba

    from slopelander.model import UserEffect

    @numba.njit
    def nothing(t, st, ctx, up, out):
        return

    with pytest.raises(ValueError, match="built-in effects"):
        ReferenceLanding(model.with_user_effect(UserEffect("nothing", "", nothing)), LandingConditions())
