"""How close a landing came to flipping, in the summary and the plot; rigid gear plots say so."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander.cli import main
from slopelander.model import LandingConditions, Model, Outcome, simulate
from slopelander.plots.landing import landing_figure, landing_title

STEEP = LandingConditions(slope_deg=35, speed=2.7, tau_up=1.7, tau_down=1.7, reverse_percent=100)


def test_the_margin_is_the_flip_criterion_less_the_largest_pitch() -> None:
    tr = simulate(STEEP)
    largest = max(-tr.result.min_pitch_deg, float(np.degrees(np.abs(tr.states[:, 2]).max())))
    assert largest > 60  # the swing the issue describes
    assert tr.pitch_margin_deg == pytest.approx(Model.default().criteria.flip_pitch_deg - largest)
    first = tr.summary().splitlines()[0]
    margin = f"{tr.pitch_margin_deg:.0f}"
    assert first.startswith("outcome: ")  # under-used (ideal before eq. 3/4 applied per leg)
    assert first.endswith(f", closest to flipping: {margin} deg margin (flip at 80 deg)")
    assert "closest to flipping" in landing_title(tr)


def test_a_flipped_landing_has_no_margin_left() -> None:
    tr = simulate(LandingConditions(slope_deg=50, speed=3.0, tau_up=1.7, tau_down=1.7))
    assert tr.result.outcome is Outcome.FLIP
    assert tr.pitch_margin_deg <= 0
    assert "pitch passed the 80 deg flip criterion" in tr.summary().splitlines()[0]


def test_a_rigid_gear_plot_says_rigid_and_names_no_torque() -> None:
    cond = LandingConditions(slope_deg=20, speed=2.0, tau_up=1.7, tau_down=1.7)
    rigid = simulate(cond, Model.default().rigid())
    fsa = simulate(cond)
    assert np.ptp(rigid.joint_angles, axis=0).max() < 1e-9  # the joints really are locked
    fig = landing_figure(rigid)
    texts = [ax.get_title() for ax in fig.axes] + [ax.get_ylabel() for ax in fig.axes]
    assert any("rigid gear" in t for t in texts)
    assert not any("τ" in t or "torque" in t.lower() or "N·m" in t for t in texts)
    assert "FSA legs, τ up/down 1.7/1.7 N·m" in landing_title(fsa) and "rigid" not in landing_title(fsa)


def test_simulate_rigid_prints_no_friction_torque(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--slope", "20", "--rigid"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert "rigid gear (legs locked at 37.5/37.5 deg)" in first and "tau" not in first
