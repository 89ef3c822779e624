"""Hidden user effects: a law written in a user's file, hidden in the synthetic truth, is found
by ``diagnose`` from its file, ranked first among the built-in candidates and the other user
effects, and its parameter comes back. One hidden law per seam: the joint's torque law, the
foot's friction law, the contact's normal-force law, forces at named points.

The joint and foot laws are shown on the steeper half of the paper's spread (22.5-45 deg,
where feet slide and joints slip: on shallow slopes neither seam acts); the normal-force law
and the point force act on every drop and are shown on the whole spread. The base model fits
k_g's damping and the leg's flex; mu_k is taken as measured (a tilt test): fitted together
with a slip-speed friction law on so few drops, the two trade off and the fit fixes their
combination, not each (docs/effects.md has the numbers).

In the default suite: the foot's friction law found from its file, one seed; the other seams and
seeds take minutes each and are marked ``proof`` (``python3 -m pytest -m proof``).
"""

from pathlib import Path

import pytest

from slopelander.ident.diagnose import diagnose
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize
from slopelander.model import load_effects

#: its tests share a base fit and datasets (base, user_effects): one worker, file order (tests/conftest.py)
pytestmark = [
    pytest.mark.xdist_group("ident/diagnose_user_effects"),
    pytest.mark.timeout(1200),
]  # long searches

ROOT = Path(__file__).resolve().parents[2]
FILES = {
    "viscous_joint": ROOT / "docs" / "examples" / "effect_joint_torque.py",
    "stribeck_feet": ROOT / "docs" / "examples" / "effect_foot_friction.py",
    "slip_weakening": Path(__file__).parent / "effects" / "slip_weakening.py",
    "hunt_crossley_ground": ROOT / "docs" / "examples" / "effect_normal_force.py",
    "rotor_spin_down": Path(__file__).parent / "effects" / "rotor_spin_down.py",
}
NAMES = ["ground_damping", "flex_stiffness", "flex_damping"]
BUDGET = {"cma_evals": 150, "refit_evals": 100, "ls_evals": 10}


@pytest.fixture(scope="module")
def user_effects():
    return {name: load_effects(path)[0] for name, path in FILES.items()}


@pytest.fixture(scope="module")
def base(model):
    return model.without("downhill_torque_growth", "downhill_friction_growth")


def _steep_drops(truth, seed):
    conds = [c for c in paper_drops(16, seed=0) if c.slope_deg >= 22.5]
    assert len(conds) == 8
    return synthesize(truth, conds, NoiseModel(), seed=seed, duration=0.6)


JOINT = ("viscous_joint", "joint_viscous_gain", 0.05)
FOOT = ("slip_weakening", "slip_weakening", 1.0)


@pytest.mark.parametrize(
    ("hidden", "parameter", "value", "seed"),
    [
        pytest.param(*JOINT, 1, marks=pytest.mark.proof),
        pytest.param(*JOINT, 2, marks=pytest.mark.proof),
        (*FOOT, 1),
        pytest.param(*FOOT, 2, marks=pytest.mark.proof),
        pytest.param(*FOOT, 3, marks=pytest.mark.proof),
    ],
    ids=[
        "joint_torque_law-1",
        "joint_torque_law-2",
        "foot_friction_law-1",
        "foot_friction_law-2",
        "foot_friction_law-3",
    ],
)
def test_hidden_user_effect_is_found_from_its_file(base, user_effects, hidden, parameter, value, seed):
    truth = base.with_user_effect(user_effects[hidden]).with_params(**{parameter: value})
    drops = _steep_drops(truth, seed)
    # every user file is a candidate, the hidden one among them; so are the built-ins the
    # base model lacks
    d = diagnose(base, drops, user_effects=list(user_effects.values()), names=NAMES, seed=seed, **BUDGET)
    assert sorted(r.candidate.name for r in d.results) == sorted(
        ["downhill_friction_growth", "downhill_torque_growth", *user_effects]
    )
    best = d.missing
    assert best is not None and best.candidate.name == hidden, d.table()
    assert d.results[0] is best
    assert 1 - best.validation_nrmse / d.base_validation >= 0.30, d.table()
    assert best.values()[parameter] == pytest.approx(value, rel=0.15), d.table()
    assert f"missing: {hidden}" in d.verdict()


def _found(base, user_effects, hidden, drops, seed, **budget):
    """Diagnose with every user file and the built-ins the base lacks as candidates; the hidden
    effect must be ranked first, named missing and cut the validation error by 30 %."""
    kw = {**BUDGET, **budget}
    d = diagnose(base, drops, user_effects=list(user_effects.values()), names=NAMES, seed=seed, **kw)
    assert sorted(r.candidate.name for r in d.results) == sorted(
        ["downhill_friction_growth", "downhill_torque_growth", *user_effects]
    )
    best = d.missing
    assert best is not None and best.candidate.name == hidden, d.table()
    assert d.results[0] is best
    assert 1 - best.validation_nrmse / d.base_validation >= 0.30, d.table()
    assert f"missing: {hidden}" in d.verdict()
    return d, best


@pytest.mark.proof
@pytest.mark.parametrize("seed", [1, 2])
def test_hidden_normal_force_law_is_found_from_its_file(base, user_effects, seed):
    """A Hunt-Crossley ground (docs/examples/effect_normal_force.py at its declared values) in
    the truth, the linear spring-damper in the analysed model. Its damping alpha, which sets how
    much of the impact the ground takes, comes back within 15 %; its stiffness, which sets a
    sink of a fraction of a millimetre, only roughly (the motion capture's noise is 1 mm).

    Marked a known failure on seed 2 "under the new decision rule, not yet re-measured" (the
    sign-flip test over held-out drops, 2026-11-26). Re-measured with that rule as it stands
    (the mean gain, the 2 % minimum, the missing candidate refitted on every drop): seed 2 is
    found, p = 0.0107 over 1024 sign flips of 10 drops, held-out NRMSE 0.0634 -> 0.0409 (-36 %),
    hc_damping 0.514, hc_stiffness 2.0e6 (the fits of the two groups, on 5 drops each, had
    scattered 6.8e6..8.8e6 and 0.24..0.51: the values asserted are the refit on all drops)."""
    hc = user_effects["hunt_crossley_ground"]
    truth = base.with_user_effect(hc)
    drops = synthesize(truth, paper_drops(10, seed=0), NoiseModel(), seed=seed, duration=0.6)
    d, best = _found(base, user_effects, "hunt_crossley_ground", drops, seed)
    values = best.values()
    assert values["hc_damping"] == pytest.approx(hc.parameters["hc_damping"].value, rel=0.15), d.table()
    assert 0.5 < values["hc_stiffness"] / hc.parameters["hc_stiffness"].value < 2.0, d.table()


@pytest.mark.proof
@pytest.mark.parametrize("seed", [1, 2])
def test_hidden_point_force_is_found_from_its_file(base, user_effects, seed):
    """Rotors coasting down after a motor cut at touchdown (tests/ident/effects/
    rotor_spin_down.py): a force at the rotor hubs, 3 N each at touchdown."""
    truth = base.with_user_effect(user_effects["rotor_spin_down"]).with_params(spin_down_thrust=3.0)
    drops = synthesize(truth, paper_drops(10, seed=0), NoiseModel(), seed=seed, duration=0.6)
    # the rotors' lift trades off against the ground damping: with 100 refit evaluations the
    # search stopped at 2.39 N on seed 1 (300: 2.94 N; measured 2026-11-23)
    d, best = _found(base, user_effects, "rotor_spin_down", drops, seed, refit_evals=300)
    assert best.values()["spin_down_thrust"] == pytest.approx(3.0, rel=0.15), d.table()


def test_declared_bounds_and_neutral_values_drive_the_search(base, user_effects):
    from slopelander.ident.diagnose import Candidate, candidate_params, neutral_values
    from slopelander.ident.fit import DEFAULT_BOUNDS, apply, resolve_params

    joint = user_effects["viscous_joint"]
    m = base.with_user_effect(joint)
    (p,) = resolve_params(m, ["joint_viscous_gain"])
    assert (p.low, p.high) == (0.0, 0.2)  # the file's declaration, no --fit bounds needed
    (q,) = resolve_params(m, ["joint_viscous_gain"], {"joint_viscous_gain": (0.01, 0.1)})
    assert (q.low, q.high) == (0.01, 0.1)  # given bounds win
    cand = Candidate(joint.name, tuple(joint.parameters), joint)
    assert neutral_values(cand) == {"joint_viscous_gain": 0.0}
    (c,) = candidate_params(base, cand, [], DEFAULT_BOUNDS)
    assert (c.low, c.high) == (0.0, 0.2)
    fitted = apply(m, [p], [0.07])
    assert fitted.parameter("joint_viscous_gain") == pytest.approx(0.07)
    assert fitted.user_effects[0].parameters["joint_viscous_gain"].provenance == "identified"
