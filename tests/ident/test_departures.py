"""Verdicts on a truth whose base physics departs from the model's (slopelander.ident.truth
DEPARTURES): with nothing hidden, diagnose must not name an effect that only absorbs the
departure. The departure is first shown to be visible (its size above the noise floor), so the
test has something to resist; a small case (6 drops, small budgets) of the benchmark
benchmarks/ident_truth_table.py --departures, whose runs are in benchmarks/results. The rule
that stops it (a named effect must beat the base physics' freed shapes on held-out drops) is
also tested on diagnoses assembled from given per-drop errors."""

from pathlib import Path

import numpy as np
import pytest

from slopelander.commands.diagnose import DIAGNOSE_EXIT
from slopelander.ident.compare import compare, state_ranges
from slopelander.ident.diagnose import Candidate, CandidateResult, Diagnosis, diagnose
from slopelander.ident.evidence import SignFlipTest, noise_floor
from slopelander.ident.recording import Drop
from slopelander.ident.synth import paper_drops
from slopelander.ident.truth import DEPARTURES, MotionCapture
from slopelander.ident.truth.dataset import truth_dataset
from slopelander.model import LandingConditions, load_effects

EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"
#: the laws a user would try for a joint or a foot that departs: a viscous joint, slip-weakening feet
CANDIDATES = [EXAMPLES / "effect_joint_torque.py", EXAMPLES / "effect_foot_friction.py"]
SMALL = {"cma_evals": 40, "refit_evals": 30, "ls_evals": 5}


@pytest.mark.parametrize(
    "departure",
    # joint_exp_weakening falls exponentially, outside the Gaussian family of the joint_breakaway
    # alternative: on this seed a viscous joint was named until the alternatives' refits were
    # also searched from the centre of their bounds; over 8 control seeds one is still named
    # (benchmarks/results/2026-12-08-departures-guard.md)
    ["tanh_friction", "joint_stribeck", "joint_exp_weakening"],
)
@pytest.mark.slow
@pytest.mark.xdist_group("ident/departures")
@pytest.mark.timeout(1200)
def test_a_departing_base_physics_is_not_named_as_an_effect(model, departure):
    base = model.without("downhill_torque_growth", "downhill_friction_growth")
    dep = DEPARTURES[departure]
    drops = truth_dataset(base, paper_drops(6, seed=0), None, MotionCapture(), seed=1, departure=dep)
    ranges = state_ranges(drops)
    size = compare(base, drops, ranges).nrmse / noise_floor(base, drops, ranges, seed=1)
    assert size > 1.5, f"{departure} is {size:.2f} noise floors: too small to test anything"
    users = [e for f in CANDIDATES for e in load_effects(f)]
    names = ["ground_damping", "flex_stiffness", "flex_damping"]
    d = diagnose(base, drops, user_effects=users, names=names, seed=1, workers=1, **SMALL)
    assert d.missing is None, d.verdict() + "\n" + d.table()
    assert d.kind != "missing"


# -- the rule, on assembled diagnoses --------------------------------------------------------
BASE_MSE = np.full(6, 0.04**2)
NAMED_GAINS = np.array([0.9, 0.5, 0.8, 0.4, 0.7, 0.6])  # passes: p 1/64 over 6 drops


def _result(name: str, log_gains: np.ndarray, p: float = float("nan")) -> CandidateResult:
    r = CandidateResult(Candidate(name, (f"{name}_k",)), 0.1, p=p)
    r.fits = [type("F", (), {"values": {f"{name}_k": 1.0}, "train_nrmse": 0.03})()]
    r.heldout_mse = BASE_MSE / np.exp(log_gains)
    r.heldout = np.sqrt(r.heldout_mse)
    return r


TIED = NAMED_GAINS + np.array([0.1, -0.2, 0.15, -0.1, -0.05, 0.1])  # the named one over it: p 0.56


def _diagnosis(alternative_gains: np.ndarray | None, on_top: np.ndarray | None = None) -> Diagnosis:
    """A viscous joint that passed the test; a freed joint law with ``alternative_gains``; the
    viscous joint refitted on top of it with ``on_top`` (per-drop log gains over the base)."""
    t = np.array([0.0, 0.01])
    drops = [Drop(f"d{i}", t, np.zeros((2, 6)), LandingConditions(slope_deg=5.0 * i)) for i in range(6)]
    test = SignFlipTest(np.zeros(1), np.array([1 / 64]), 64, True, 0.1)
    d = Diagnosis(
        [], [_result("viscous_joint", NAMED_GAINS, 1 / 64)], np.sqrt(BASE_MSE), BASE_MSE, drops, test, 0.01
    )
    if alternative_gains is not None:
        d.alternatives = [_result("joint_breakaway", alternative_gains)]
    if on_top is not None:
        d.on_top = {"joint_breakaway": _result("viscous_joint", on_top)}
    return d


@pytest.mark.parametrize(
    "on_top",
    [
        pytest.param(None, id="not-refitted-with-it"),
        pytest.param(TIED + 0.005, id="adds-half-a-percent"),  # passes the test, below MIN_GAIN
        pytest.param(TIED + np.array([0.3, -0.3, 0.2, -0.2, 0.1, -0.1]), id="adds-noise"),
    ],
)
def test_an_effect_a_freed_base_law_explains_as_well_is_not_named(on_top):
    """The named effect's per-drop gains over the freed joint law change sign from drop to drop
    (p 0.56 > 0.05), and refitted on top of that law it adds nothing that passes: these drops
    cannot tell a viscous joint from another joint law, so nothing is named; the verdict says
    which alternative, and the exit code is "too small to tell"'s."""
    d = _diagnosis(TIED, on_top)
    assert d.passed is not None and d.missing is None and d.final is None
    assert d.kind == "base_physics" and DIAGNOSE_EXIT[d.kind] == DIAGNOSE_EXIT["too_small"]
    a, _ = d.base_physics(d.passed)
    assert a.candidate.name == "joint_breakaway" and d.beats(d.passed, a) > 0.05
    told = "missing, but the data cannot tell viscous_joint from a difference in the base physics"
    assert d.verdict().startswith(f"{told} (joint_breakaway")
    js = d.to_dict()
    assert js["verdict"] == "base_physics" and js["base_physics"]["name"] == "joint_breakaway"
    assert "joint_breakaway (the base physics' shape freed, not a mechanism)" in d.weighing()


@pytest.mark.parametrize(
    ("alternative", "on_top"),
    [
        pytest.param(NAMED_GAINS - 0.3, None, id="beaten-on-every-drop"),  # p 1/64
        pytest.param(np.full(6, 0.01), None, id="explains-nothing"),  # gain 0.5 % < MIN_GAIN
        pytest.param(None, None, id="none-refitted"),
        # tied alone, but on top of the freed law it still gains 0.3 on every drop (p 1/64): a
        # mechanism acting where the freed law does not (a rotor spin-down beside joint breakaway)
        pytest.param(TIED, TIED + 0.3, id="still-gains-on-top"),
    ],
)
def test_an_effect_that_beats_every_freed_base_law_is_named(alternative, on_top):
    """A real mechanism explains what a freed base law cannot: it is named as before."""
    d = _diagnosis(alternative, on_top)
    assert d.missing is d.passed and d.missing.candidate.name == "viscous_joint"
    assert d.kind == "missing" and d.verdict().startswith("missing: viscous_joint")
