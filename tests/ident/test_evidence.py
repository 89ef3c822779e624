"""The pieces of diagnose's evidence: the sign-flip test's error rate, the noise floor, nested
candidates, what each verdict says; and the defects fixed on the way (edge rates, singular
directions, a fit that starts from the given model)."""

import math
from pathlib import Path

import numpy as np
import pytest

from slopelander.ident.compare import compare, state_ranges
from slopelander.ident.diagnose import (
    Candidate,
    CandidateResult,
    Diagnosis,
    candidates_for,
    screen,
)
from slopelander.ident.evidence import SignFlipTest, noise_floor, sign_flip_test
from slopelander.ident.fit import fit, identifiability, make_param, resolve_params
from slopelander.ident.synth import NoiseModel, differentiate, paper_drops, synthesize
from slopelander.model import load_effects

EFFECTS = Path(__file__).parent / "effects"
ROOT = Path(__file__).resolve().parents[2]


def test_sign_flip_test_keeps_its_error_rate_with_many_candidates():
    """Seven correlated candidates whose held-out gains are noise (symmetric about a small loss,
    as extra parameters fitted to noise give): the smallest corrected p falls below 5 % in at
    most 5 % of datasets. A flat 'best of seven' rule would pick one every time."""
    rng = np.random.default_rng(0)
    hits = 0
    for _ in range(400):
        common = rng.normal(0, 1, 10)
        gains = np.array([0.7 * common + rng.normal(0, 0.7, 10) - 0.05 for _ in range(7)])
        hits += sign_flip_test(gains).p.min() <= 0.05
    assert hits / 400 <= 0.05


def test_sign_flip_test_finds_a_consistent_gain():
    rng = np.random.default_rng(1)
    gains = np.array([rng.normal(0.4, 0.2, 10), rng.normal(0.0, 0.2, 10), rng.normal(0.0, 0.2, 10)])
    t = sign_flip_test(gains)
    assert t.exact and t.patterns == 1024
    assert t.p[0] <= 2 / 1024 and t.p[0] == t.p.min()


def test_rates_at_a_recordings_edges_are_as_quiet_as_inside():
    """Before: differences at the first and last three samples, 3.7 to 7.4x the noise."""
    rng = np.random.default_rng(2)
    t = np.arange(200) * 0.005
    noise = rng.normal(0, 1e-3, (4000, 200, 1))
    rates = np.array([differentiate(n, t, 7)[:, 0] for n in noise])
    sd = rates.std(axis=0)
    inside = sd[3:-3].mean()
    assert sd[:3].max() < 1.2 * inside and sd[-3:].max() < 1.2 * inside
    # and a straight line's slope is exact everywhere
    line = (2.0 * t - 1.0)[:, None]
    assert np.allclose(differentiate(line, t, 7), 2.0)


def test_a_parameter_on_a_flat_direction_is_not_identified():
    """A Jacobian column of zeros (a stick-slip parameter the drops never move) was reported
    +-0: the pseudo-inverse dropped the direction and read it as perfectly known."""
    params = [make_param("a", 0.0, 1.0), make_param("b", 0.0, 1.0)]
    rng = np.random.default_rng(3)
    J = np.column_stack([rng.normal(size=50), np.zeros(50)])
    r = rng.normal(0, 0.01, 50)
    ci, warns = identifiability(params, J, np.array([0.5, 0.5]), r, {"a": 0.5, "b": 0.5})
    assert math.isfinite(ci["a"]) and ci["a"] > 0
    assert ci["b"] == math.inf
    assert any("b is not identified" in w for w in warns)


def test_fit_starts_from_the_given_model_and_never_ends_worse(model):
    """Before, the search began at the centre of the bounds: on a correct model a short
    search made it worse."""
    drops = synthesize(model, paper_drops(3, seed=5), NoiseModel(), seed=5, duration=0.4)
    params = resolve_params(model, ["ground_damping", "friction_kinetic"])
    r = fit(model, drops, params, cma_evals=16, ls_evals=2, workers=1)
    assert r.start_values == pytest.approx({"ground_damping": 437.0, "friction_kinetic": 0.8})
    assert r.cost <= r.start_cost
    assert r.values["ground_damping"] == pytest.approx(437.0, rel=0.3)
    centre = fit(model, drops, params, cma_evals=16, ls_evals=2, workers=1, from_centre=True)
    assert centre.start_values["friction_kinetic"] == pytest.approx(0.7)


def test_noise_floor_is_what_the_truth_scores_on_its_own_recording(model):
    drops = synthesize(model, paper_drops(4, seed=1), NoiseModel(), seed=7, duration=0.5)
    ranges = state_ranges(drops)
    floor = noise_floor(model, drops, ranges, draws=3)
    truth_score = compare(model, drops, ranges).nrmse
    assert floor == pytest.approx(truth_score, rel=0.15)
    undeclared = [d.__class__(d.name, d.t, d.states, d.conditions, d.outcome, d.source, {}) for d in drops]
    assert noise_floor(model, undeclared, ranges) is None


def test_a_candidate_at_its_neutral_values_is_the_base_model(model):
    """The normal-force seam reads the model's own ground, so a law built on it is nested: at
    its neutral exponent it gives the base model's residual. A Hunt-Crossley ground (a law of
    its own) is not, and diagnose says so."""
    base = model.without("downhill_torque_growth", "downhill_friction_growth")
    drops = synthesize(base, paper_drops(3, seed=2), NoiseModel(), seed=2, duration=0.4)
    ranges = state_ranges(drops)
    power = load_effects(EFFECTS / "ground_power.py")
    hc = load_effects(ROOT / "docs" / "examples" / "effect_normal_force.py")
    cands = [c for c in candidates_for(base, power + hc) if c.user is not None]
    params = resolve_params(base, ["ground_damping"])
    out = screen(base, drops, cands, params, ranges, {})
    assert out["ground_power"].nested, out["ground_power"].note
    assert out["ground_power"].sensitivity.max() > 0
    assert not out["hunt_crossley_ground"].nested
    assert "no neutral value for hc_stiffness" in out["hunt_crossley_ground"].note


FIXED_GROUND = """
import numba
from slopelander.model.effects import EffectParameter, UserEffect

@numba.njit
def soft_ground(t, st, ctx, up, point, depth, rate):
    k, b = 2.17e4, 437.0  # the paper's ground written as constants: the mistake
    force = up[0] * k * depth + b * rate
    return (force, up[0] * k, b) if force > 0.0 else (0.0, 0.0, 0.0)

EFFECTS = [UserEffect("fixed_ground", "a scaled ground, its values fixed", normal_force=soft_ground,
    parameters={"ground_scale": EffectParameter(1.0, "1", 0.5, 2.0, "assumed", neutral=1.0)})]
"""


def test_a_candidate_hard_coding_the_ground_is_told_to_read_the_accessors(model, tmp_path):
    """At its neutral value a law with the ground's values as constants is the model only while
    the model's ground is those values; on another ground it is not nested, and the note says how
    to write it nested (docs/effects.md, "Parameters")."""
    base = model.without("downhill_torque_growth", "downhill_friction_growth").with_params(
        ground_stiffness=3.0e4
    )
    drops = synthesize(base, paper_drops(3, seed=2), NoiseModel(), seed=2, duration=0.4)
    path = tmp_path / "fixed_ground.py"
    path.write_text(FIXED_GROUND)
    cands = [c for c in candidates_for(base, load_effects(path)) if c.user is not None]
    out = screen(base, drops, cands, resolve_params(base, ["ground_damping"]), state_ranges(drops), {})
    assert not out["fixed_ground"].nested
    note = out["fixed_ground"].note
    assert "state.ground_stiffness(ctx)" in note, note
    # the section it points at is one the page has (it named a "Nested effects" that was not there)
    section = note.split("docs/effects.md, '")[1].split("'")[0]
    assert f"\n## {section}\n" in (ROOT / "docs" / "effects.md").read_text(), section


def test_a_built_in_candidate_that_is_not_nested_is_not_told_to_declare_neutral(model):
    """leg_flex has no value within its bounds that switches it off (rigid legs are an infinite
    stiffness). The note told the user to "declare neutral=..." on an effect they cannot edit."""
    base = model.without("downhill_torque_growth", "downhill_friction_growth", "leg_flex")
    drops = synthesize(base, paper_drops(2, seed=2), NoiseModel(), seed=2, duration=0.3)
    cands = [c for c in candidates_for(base) if c.name == "leg_flex"]
    out = screen(base, drops, cands, resolve_params(base, ["ground_damping"]), state_ranges(drops), {})
    note = out["leg_flex"].note
    assert not out["leg_flex"].nested
    assert "declare" not in note and note.startswith("built-in: no value of"), note
    assert "flex_stiffness, flex_damping" in note


def _diagnosis(base_nrmse, cand_nrmse, floor, p):
    n = len(base_nrmse)
    cand = CandidateResult(Candidate("leg_flex", ("flex_stiffness",)), 0.1, p=p)
    cand.fits = [type("F", (), {"values": {"flex_stiffness": 10.0}, "train_nrmse": 0.01})()]
    cand.heldout = np.asarray(cand_nrmse)
    cand.heldout_mse = cand.heldout**2
    cand.sensitivity = np.linspace(0.0, 1.0, n)
    drops = synthesize_stub(n)
    b = np.asarray(base_nrmse)
    test = SignFlipTest(np.array([2.0]), np.array([p]), 1024, True, 2.5)
    return Diagnosis([], [cand], b, b**2, drops, test, floor)


def synthesize_stub(n):
    from slopelander.ident.recording import Drop
    from slopelander.model import LandingConditions

    t = np.array([0.0, 0.01])
    return [
        Drop(f"drop{i:02d}", t, np.zeros((2, 6)), LandingConditions(slope_deg=4.0 * i, speed=2.0))
        for i in range(n)
    ]


def test_the_verdicts_say_what_the_residual_and_the_test_show():
    # at the floor: nothing missing, and how much could hide
    d = _diagnosis([0.0105] * 10, [0.0104] * 10, 0.010, 0.4)
    assert d.verdict().startswith("nothing missing: the held-out NRMSE 0.0105 is at the noise floor")
    assert "nothing larger than 0.0066 NRMSE" in d.verdict()
    # a consistent but negligible gain (a refit's extra search, not an effect) is not named
    d = _diagnosis([0.0105] * 10, [0.0104] * 10, 0.010, 0.003)
    assert d.missing is None and d.verdict().startswith("nothing missing")
    # nine floors and no candidate: missing, but not among them
    d = _diagnosis([0.096] * 10, [0.095] * 10, 0.010, 0.3)
    assert d.verdict().startswith("missing, but not among these candidates")
    assert "and no candidate explains it (" in d.verdict()
    # one that removes much of it without passing the test is not said to explain nothing
    d = _diagnosis([0.096] * 10, [0.040] * 10, 0.010, 0.3)
    v = d.verdict()
    assert v.startswith("missing, but not among these candidates") and "no candidate explains it" not in v
    assert "no candidate passes the test, though leg_flex lowers it 58 % on held-out drops" in v
    # a moderate excess no candidate pins down: too small to tell, and where to drop next
    d = _diagnosis([0.014] * 10, [0.0135] * 10, 0.010, 0.2)
    v = d.verdict()
    assert v.startswith("too small to tell with these drops") and "acts most on drop09 (36 deg" in v
    # a candidate that passes the test is named, with its evidence
    d = _diagnosis([0.03] * 10, [0.012] * 10, 0.010, 0.002)
    assert d.verdict().startswith("missing: leg_flex") and "p = 0.002" in d.verdict()
    # no declared noise: no claim about the floor
    d = _diagnosis([0.03] * 10, [0.03] * 10, None, 0.5)
    assert "declare no noise" in d.verdict()


def test_intervals_over_drops_cover_when_samples_within_a_drop_are_not_independent():
    """Each drop's noise is mostly one offset shared by its samples (as a smooth model error
    is). Treating 400 samples as independent gave intervals that missed the truth most of the
    time; the sandwich over the 8 drops covers it about 95 % of the time."""
    rng = np.random.default_rng(4)
    params = [make_param("a", 0.0, 1.0)]
    groups = np.repeat(np.arange(8), 50)
    x = rng.uniform(0.5, 1.5, 400)
    x += np.repeat(rng.normal(0, 0.5, 8), 50)
    J = x[:, None]
    cover = {"drops": 0, "samples": 0}
    for _ in range(300):
        y = 0.5 * x + np.repeat(rng.normal(0, 0.2, 8), 50) + rng.normal(0, 0.01, 400)
        a = float(np.linalg.lstsq(J, y, rcond=None)[0][0])
        r = J[:, 0] * a - y
        for key, g in (("drops", groups), ("samples", None)):
            ci, _ = identifiability(params, J, np.array([a]), r, {"a": a}, g)
            cover[key] += abs(a - 0.5) <= ci["a"]
    assert 0.88 <= cover["drops"] / 300 <= 0.99
    assert cover["samples"] / 300 < 0.5


def test_an_effect_acting_on_some_drops_is_not_hidden_by_tiny_consistent_gains():
    """Studentised, six candidates with tiny equal losses on every drop reached huge values in
    the flipped patterns and hid a large gain on six of ten drops (p 0.08 in a real run)."""
    rng = np.random.default_rng(5)
    real = np.array([1.2, 0.9, 0.8, 0.6, 0.5, 0.4, 0.01, -0.01, 0.02, -0.02])
    tiny = [-0.001 + rng.normal(0, 1e-5, 10) for _ in range(6)]
    t = sign_flip_test(np.array([real, *tiny]))
    assert t.p[0] <= 0.05 and t.p[1:].min() > 0.5


def test_a_recordings_first_and_last_rates_are_centred_as_the_models_are(model):
    """``meta.rates`` ``lsq_slope``: a window centred on every sample, the first and last too
    (the take runs on beyond its export). The model used to be observed with a one-sided
    difference there (window 3) or the first window's slope: its rates at the edges then
    differed from the recording's central differences by half a frame of acceleration (z rate
    0.025 m/s in flight at 200 Hz), and the noise floor counted twice the noise there."""
    from slopelander.ident.observe import predict
    from slopelander.ident.recording import Drop
    from slopelander.ident.synth import true_states
    from slopelander.model import LandingConditions

    cond = LandingConditions(slope_deg=20.0, speed=2.0, tau_up=1.1, tau_down=1.7)
    dt = 0.005
    take = np.arange(-11, 102) * dt  # the take; the export is its frames 1..-2
    truth, _ = true_states(model, cond, take)
    central = (truth[2:, :3] - truth[:-2, :3]) / (2 * dt)
    for window in (3, 7):
        h = window // 2
        t = take[h : len(take) - h]
        states = np.column_stack([truth[h : len(take) - h, :3], central[h - 1 : len(central) - h + 1]])
        if window == 7:  # a 7-frame least-squares slope over the take, cut to the export
            states[:, 3:] = differentiate(truth[:, :3], take, 7)[h : len(take) - h]
        drop = Drop("d", t, states, cond, None, "", {"rates": {"method": "lsq_slope", "window": window}})
        sim, _ = predict(model, drop, outcome=False)
        err = np.abs(sim[:, 3:] - states[:, 3:])
        inside = err[h:-h].max(axis=0)
        assert (err[0] <= 2 * inside + 1e-4).all(), (window, err[0], inside)
        assert (err[-1] <= 2 * inside + 1e-4).all(), (window, err[-1], inside)


def test_noise_floor_counts_the_edges_as_the_recording_has_them(model):
    """Short recordings (7 samples after contact) of the model's own landing, central
    differences centred on every sample: the declared noise floor is what the truth scores on
    them. Counting the last sample's rate as a one-sided difference (4x its variance) lifted
    the floor above the truth's score."""
    from slopelander.ident.recording import Drop
    from slopelander.ident.synth import true_states
    from slopelander.model import LandingConditions

    cond = LandingConditions(slope_deg=20.0, speed=2.0, tau_up=1.1, tau_down=1.7)
    dt, lat, sd, ang = 0.005, 0.002, 1e-3, 0.3
    take = np.arange(-5, 8) * dt  # the export: its frames 1..-2 (-0.02..0.03 s)
    truth, _ = true_states(model, cond, take - lat)
    rng = np.random.default_rng(5)
    meta = {
        "rates": {"method": "lsq_slope", "window": 3},
        "noise": {"position_sd_m": sd, "angle_sd_deg": ang, "latency_s": lat},
    }
    drops = []
    for i in range(150):
        pos = truth[:, :3] + rng.normal(0.0, [sd, sd, math.radians(ang)], (len(take), 3))
        rates = (pos[2:] - pos[:-2]) / (2 * dt)
        states = np.column_stack([pos[1:-1], rates])
        drops.append(Drop(f"d{i}", take[1:-1], states, cond, None, "central differences", meta))
    ranges = state_ranges(drops)
    floor = noise_floor(model, drops, ranges, draws=2, seed=1)
    score = compare(model, drops, ranges).nrmse
    assert floor == pytest.approx(score, rel=0.04)


def test_a_named_candidates_refit_far_above_the_floor_says_its_values_are_where_it_stopped():
    """Round pads hidden (seed 1): the refit on all drops ended at 3.4 noise floors and printed
    a radius of 0.0580 +- 0.0008 m against the truth's 0.040. Above 1.2 floors the verdict says
    the values hold only where the search stopped; at the floor it says nothing more."""
    from types import SimpleNamespace

    d = _diagnosis([0.03] * 10, [0.012] * 10, 0.010, 0.002)
    final = dict(values={"flex_stiffness": 12.0}, ci95={"flex_stiffness": 0.5}, intervals="profile", lags={})
    d.final = SimpleNamespace(train_nrmse=0.034, warnings=[], **final)
    text = d.verdict()
    assert text.startswith("missing: leg_flex") and "flex_stiffness = 12 +- 0.5" in text
    assert "3.4x the noise floor (NRMSE 0.0340)" in text and "hold only where it stopped" in text
    d.final = SimpleNamespace(train_nrmse=0.0105, warnings=[], **final)
    assert "stopped" not in d.verdict()
    assert d.to_dict()["missing"]["refit_nrmse"] == 0.0105


def test_a_named_candidates_verdict_carries_what_its_intervals_reading_said_of_its_values():
    """Round pads hidden (seed 1): the inset's profile was rough (a flip came and went along it)
    and its interval was widened; the verdict says so beside the values, and leaves out what was
    said of a base parameter's interval (the JSON keeps every warning)."""
    from types import SimpleNamespace

    d = _diagnosis([0.03] * 10, [0.012] * 10, 0.010, 0.002)
    rough = "flex_stiffness: rough profile (...), interval widened 3.2x"
    warnings = [rough, "ground_damping: one drop alone makes the profile's minimum"]
    final = dict(values={"flex_stiffness": 12.0}, ci95={"flex_stiffness": 1.6}, intervals="profile", lags={})
    d.final = SimpleNamespace(train_nrmse=0.0105, warnings=warnings, **final)
    text = d.verdict()
    assert f"over drops; {rough})" in text and "ground_damping" not in text
    assert d.to_dict()["missing"]["warnings"] == warnings
