"""A landing flown step by step and judged by LandingJudge ends as ``simulate`` predicts from the
conditions the judge recorded at first contact: one physics, the same inputs, the same outcome."""

from __future__ import annotations

import math

import pytest

from slopelander.model import simulate
from slopelander.model.judge import LandingJudge
from slopelander.model.stepper import Stepper

H = 1.0 / 1200.0  # the simulated vehicle's physics step


def fly(slope_deg: float, reverse: float, tau: tuple[float, float], delay: float = 0.03) -> LandingJudge:
    """Take off from rest on the slope, climb for 0.3 s, cut the rotors, fall, land; reverse
    ``reverse`` (0..1) from ``delay`` s after first contact."""
    s = Stepper(slope_deg=slope_deg)
    s.set_friction(*tau)
    s.place(height=0.0)
    s.step(0.3, 0.0, 0.0)  # at rest on the surface: an old contact the judge must forget
    judge = LandingJudge(s)
    up = 1.3 * s.hover_command()
    for _ in range(int(0.3 / H)):
        s.step(H, up, up)
        judge.update(H, up, up)
    assert judge.armed and judge.impact is None
    for _ in range(int(3.0 / H)):
        t_imp = s.st[35]  # kernel.S_TIMP
        u = -reverse if judge.impact is not None and s.t - t_imp >= delay else 0.0
        s.step(H, u, u)
        if judge.update(H, u, u):
            break
    assert judge.result is not None
    return judge


@pytest.mark.parametrize(
    ("slope_deg", "reverse", "tau"),
    [(20.0, 0.0, (1.7, 1.7)), (20.0, 1.0, (2.3, 1.2)), (40.0, 1.0, (0.8, 3.0))],  # under-used, end of travel
)
def test_a_stepped_landing_ends_as_the_model_predicts_from_its_impact(slope_deg, reverse, tau) -> None:
    judge = fly(slope_deg, reverse, tau)
    imp, pr = judge.impact, judge.profile
    assert imp.vz < -1.0 and imp.slope_deg == slope_deg
    assert (imp.tau_up, imp.tau_down) == pytest.approx(tau)
    assert max(abs(w) for w in imp.rotor_speed) < 0.01  # rotors stopped well before contact
    if reverse:
        assert pr.reverse_percent == pytest.approx(100.0 * reverse)
        assert pr.reverse_delay == pytest.approx(0.03, abs=2 * H)
    else:
        assert math.isnan(pr.reverse_delay)
    predicted = simulate(judge.conditions()).result
    got = judge.result
    assert got.outcome == predicted.outcome, (got, predicted)
    assert got.slide == pytest.approx(predicted.slide, abs=0.02)
    assert got.min_pitch_deg == pytest.approx(predicted.min_pitch_deg, abs=1.0)
    if got.outcome.success:
        assert got.compression_down == pytest.approx(predicted.compression_down, abs=0.03)


def test_the_judge_waits_for_the_vehicle_to_leave_the_ground() -> None:
    s = Stepper(slope_deg=10.0)
    s.place(height=0.0)
    judge = LandingJudge(s)
    for _ in range(600):
        s.step(H, 0.0, 0.0)
        assert not judge.update(H, 0.0, 0.0)
    assert judge.result is None and not judge.armed
    with pytest.raises(ValueError, match="no landing"):
        judge.conditions()
