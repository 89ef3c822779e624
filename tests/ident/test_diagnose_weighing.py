"""What diagnose says when the evidence is weak or shared: which kind of drop would settle the
best candidate (from its per-drop held-out gains across the drops' conditions), and which other
candidates explain the residual nearly as well, with their gains and how alike their per-drop
gains are. Diagnoses are assembled from given per-drop errors (the search is tested elsewhere)."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander.ident.diagnose import Candidate, CandidateResult, Diagnosis
from slopelander.ident.evidence import SignFlipTest
from slopelander.ident.recording import Drop
from slopelander.model import LandingConditions

SLOPES = [0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0]
SPEEDS = [2.5, 1.5, 2.0, 3.0, 1.0, 2.5, 1.0, 3.0, 1.5, 2.0]  # not ordered with the slope
TORQUES = [1.1, 2.3, 1.7, 1.1, 2.3, 1.7, 2.3, 1.1, 1.7, 1.1]


def _drops() -> list[Drop]:
    t = np.array([0.0, 0.01])
    return [
        Drop(
            f"drop{i:02d}", t, np.zeros((2, 6)), LandingConditions(slope_deg=s, speed=v, tau_up=q, tau_down=q)
        )
        for i, (s, v, q) in enumerate(zip(SLOPES, SPEEDS, TORQUES, strict=True))
    ]


def _candidate(name: str, base_mse: np.ndarray, log_gains: np.ndarray, p: float) -> CandidateResult:
    r = CandidateResult(Candidate(name, (f"{name}_k",)), 0.1, p=p)
    r.fits = [type("F", (), {"values": {f"{name}_k": 1.0}, "train_nrmse": 0.01})()]
    r.heldout_mse = base_mse / np.exp(log_gains)
    r.heldout = np.sqrt(r.heldout_mse)
    return r


def _diagnosis(cands: list[CandidateResult], base_mse: np.ndarray, floor: float = 0.001) -> Diagnosis:
    test = SignFlipTest(np.zeros(len(cands)), np.array([c.p for c in cands]), 1024, True, 1.0)
    return Diagnosis([], cands, np.sqrt(base_mse), base_mse, _drops(), test, floor)


def test_the_power_line_names_the_kind_of_drop_where_the_gain_shows():
    """An effect that acts on steep drops only: its gain is large and steady at 25-45 deg, noise
    on the shallow ones. Before, diagnose said only "about N drops like these"; now the kind of
    drop (slope 25-45 deg, those drops) and how many more of them would settle it, in the printed
    line and in the JSON."""
    rng = np.random.default_rng(3)
    base_mse = np.full(10, 0.03**2)
    steep = np.array(SLOPES) >= 25.0
    g = np.where(steep, 0.8 + rng.normal(0, 0.1, 10), rng.normal(0.0, 0.4, 10))
    d = _diagnosis([_candidate("slope_law", base_mse, g, p=0.12)], base_mse)
    assert d.missing is None
    best = d.results[0]
    st = d.settle(best)
    assert st is not None and st.condition == "slope" and (st.low, st.high) == (25.0, 45.0)
    assert st.drops == [f"drop{i:02d}" for i in range(5, 10)]
    # the steep drops alone need fewer than drops like all ten, and the count follows from them
    assert st.needed < d.drops_needed(best)
    assert st.more == st.needed - 5 and st.more >= 0
    line = d.weighing()
    assert "most consistent on drops at slope 25-45 deg (drop05, drop06, drop07, drop08, drop09)" in line
    assert f"about {st.more} more such drops would settle it" in line
    js = d.to_dict()["settle"]
    assert js["condition"] == "slope" and js["unit"] == "deg" and js["needed"] == st.needed
    assert js["mean_log_gain"] == pytest.approx(float(np.mean(g[steep])))


def test_a_gain_no_condition_explains_is_told_as_drops_like_these():
    """The same gain on every kind of drop: no slope, speed or torques is singled out."""
    rng = np.random.default_rng(4)
    base_mse = np.full(10, 0.03**2)
    g = 0.3 + rng.normal(0, 0.3, 10)
    d = _diagnosis([_candidate("everywhere", base_mse, g, p=0.2)], base_mse)
    st = d.settle(d.results[0])
    if st.condition:  # a half can still look steadier by chance; then it must really need fewer
        assert st.needed < d.drops_needed(d.results[0])
    else:
        assert "more drops like these (now 10) would settle it" in d.weighing()
        assert d.to_dict()["settle"]["condition"] is None


def test_near_alike_candidates_are_reported_with_their_gains_and_correlation():
    """Two mechanisms that correct the same drops the same way (the second's per-drop gains are
    the first's, a little smaller, with a little noise), and a third that helps elsewhere: the
    named one comes with the near-alike one, its gain and the correlation of their gains; the
    third is not listed."""
    rng = np.random.default_rng(5)
    base_mse = np.full(10, 0.03**2)
    g = rng.uniform(0.4, 1.4, 10)
    first = _candidate("flex_a", base_mse, g, p=0.002)
    second = _candidate("flex_b", base_mse, 0.92 * g + rng.normal(0, 0.03, 10), p=0.004)
    other = _candidate("other", base_mse, 0.2 + rng.normal(0, 0.3, 10), p=0.3)
    d = _diagnosis([first, second, other], base_mse)
    assert d.missing is first
    alike = d.alike(first)
    assert [o.candidate.name for o, _ in alike] == ["flex_b"]
    corr = alike[0][1]
    assert corr == pytest.approx(float(np.corrcoef(g, d.log_gains(second))[0, 1])) and corr > 0.95
    js = d.to_dict()["alike"]
    assert js == [{"name": "flex_b", "gain": pytest.approx(d.gain(second)), "gain_correlation": corr}]
    assert 0.8 * d.gain(first) <= js[0]["gain"] < d.gain(first)
    line = d.weighing()
    assert f"flex_b explains nearly as much: gain {100 * d.gain(second):+.1f} %" in line
    assert f"per-drop gains correlated {corr:+.2f} with flex_a's" in line
    assert "other" not in line
