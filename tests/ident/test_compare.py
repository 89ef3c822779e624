"""compare on data whose error is known, phases, and the report."""

import numpy as np
import pytest

from slopelander.ident.compare import WEIGHTS, compare, state_ranges
from slopelander.ident.phases import PHASES, phase_labels
from slopelander.ident.recording import Drop
from slopelander.ident.report import write_report
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize

#: its tests share one clean dataset (clean): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("ident/compare")


@pytest.fixture(scope="module")
def clean(model):
    return synthesize(model, paper_drops(4, seed=3), NoiseModel.none(), duration=0.6)


def test_the_truth_scores_zero_and_matches_every_outcome(model, clean):
    c = compare(model, clean)
    assert c.nrmse < 1e-3
    assert c.outcome_matches() == (4, 4)


def test_known_offsets_give_known_nrmse(model, clean):
    """Shift the recorded z by 1 cm and pitch by 0.02 rad after contact: the NRMSE per state is
    offset / range, and the combined value weights pitch twice."""
    ranges = state_ranges(clean)
    shifted = []
    for d in clean:
        s = d.states.copy()
        s[d.t >= 0, 1] += 0.01
        s[d.t >= 0, 2] += 0.02
        shifted.append(Drop(d.name, d.t, s, d.conditions, d.outcome))
    c = compare(model, shifted, ranges)
    expect = np.zeros(6)
    expect[1] = 0.01 / ranges[1]
    expect[2] = 0.02 / ranges[2]
    np.testing.assert_allclose(c.per_state, expect, atol=1e-3)
    assert c.nrmse == pytest.approx((expect * WEIGHTS).sum() / WEIGHTS.sum(), abs=1e-3)
    assert c.state_share()["pitch"] > 0.5 or c.state_share()["z"] > 0.3


def test_a_missing_effect_shows_in_its_phase_and_window(model, clean):
    """A local error in the compression of one drop is where the worst window points.

    The error is put where compare itself finds the compression: the labels with the sliding
    phase (the drop's along-slope speed and slope). This test used drop 2 (30.8 deg, 1.34 m/s)
    and the labels from the vertical speed alone; on that drop the 0.1 s between the uphill
    foot's touch and the downhill foot's is the body falling past a lightly loaded uphill foot
    at 0.67 m/s along the slope, which the sliding rule labels "sliding" from 20 ms on, so none
    of its samples is compression any more. Drop 1 (14.5 deg) has a sliding stretch of that
    kind and then a compression: the error must be given to the compression, not to its
    neighbour."""
    d = clean[1]
    labels = phase_labels(d.t, d.states[:, 4], d.states[:, 3], d.conditions.slope_deg)
    comp = np.flatnonzero(labels == PHASES.index("compression"))
    assert comp.size >= 5 and (labels == PHASES.index("sliding")).any()
    s = d.states.copy()
    s[comp, 2] += 0.2
    bad = [clean[0], Drop(d.name, d.t, s, d.conditions, d.outcome), *clean[2:]]
    c = compare(model, bad, state_ranges(clean))
    w = c.worst_windows(1)[0]
    assert w.drop == d.name and w.state == "pitch" and w.phase == "compression"
    assert max(c.phase_share(), key=c.phase_share().get) == "compression"


def test_phases_follow_the_vertical_speed():
    t = np.arange(-0.05, 0.5, 0.005)
    vz = np.where(t < 0.1, -2.0 + 10 * np.clip(t, 0, None), np.where(t < 0.2, 0.5, -0.01))
    lab = phase_labels(t, vz)
    assert set(lab[t < 0]) == {0}
    assert set(lab[(t >= 0) & (t < 0.02)]) == {1}
    assert lab[np.searchsorted(t, 0.05)] == 2
    assert lab[np.searchsorted(t, 0.15)] == 3
    assert lab[-1] == 4


def test_report_has_a_plot_per_drop(model, clean, tmp_path):
    c = compare(model.without("leg_flex"), clean)
    out = write_report(c, tmp_path)
    text = out.read_text()
    for d in clean:
        png = tmp_path / f"{d.name}.png"
        assert png.stat().st_size > 10_000 and f"]({d.name}.png)" in text
    assert "| compression |" in text and "Worst 50 ms windows" in text


def test_a_sliding_drop_is_labelled_sliding(model):
    """On 42 deg (steeper than mu_k = 0.8 holds) on soft joints the feet slide on (outcome
    "slid"): the vertical speed never turns upward, so before the sliding phase every sample
    after contact read "compression"."""
    from slopelander.model import LandingConditions

    slid, level = synthesize(
        model,
        [
            LandingConditions(slope_deg=42.0, speed=2.5, tau_up=0.56, tau_down=0.56),
            LandingConditions(slope_deg=0.0, speed=1.5),
        ],
        NoiseModel(),
        seed=1,
        duration=0.8,
    )
    assert slid.outcome.name == "SLID"
    before = phase_labels(slid.t, slid.states[:, 4])
    assert set(before[slid.t >= 0.02]) == {PHASES.index("compression")}
    lab = phase_labels(slid.t, slid.states[:, 4], slid.states[:, 3], slid.conditions.slope_deg)
    late = slid.t > 0.3
    assert np.mean(lab[late] == PHASES.index("sliding")) > 0.6
    assert "sliding" in compare(model, [slid]).per_phase()
    lab = phase_labels(level.t, level.states[:, 4], level.states[:, 3], 0.0)
    assert PHASES.index("sliding") not in lab
