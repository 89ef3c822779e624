"""Hidden-effect proofs: drops from a truth with an effect, analysed by a model without it.

The truth is the shipped model without the two downhill-leg factors (their paper values barely
move these drops, see docs/ident.md), so the candidates the analysed model lacks are leg
flexibility and both factors. Noise is motion-capture-like; several seeds.
"""

import pytest

from slopelander.ident.diagnose import MIN_GAIN, diagnose
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize

BUDGET = {"cma_evals": 300, "refit_evals": 150}


@pytest.fixture(scope="module")
def truth(model):
    return model.without("downhill_torque_growth", "downhill_friction_growth")


@pytest.mark.parametrize("seed", [1, 2])
def test_hidden_leg_flex_is_found(truth, seed):
    drops = synthesize(truth, paper_drops(10, seed=0), NoiseModel(), seed=seed)
    d = diagnose(truth.without("leg_flex"), drops, seed=seed, **BUDGET)
    best = d.results[0]
    assert d.missing is best and best.candidate.name == "leg_flex"
    cut = 1 - best.validation_nrmse / d.base_validation
    assert cut >= 0.30, d.table()
    assert best.values()["flex_stiffness"] == pytest.approx(truth.params["flex_stiffness"], rel=0.15)
    assert "missing: leg_flex" in d.verdict()
    assert sorted(r.candidate.name for r in d.results) == [
        "downhill_friction_growth",
        "downhill_torque_growth",
        "leg_flex",
    ]
    assert all(r.fits for r in d.results)


def test_nothing_missing_when_nothing_is(truth):
    drops = synthesize(truth, paper_drops(10, seed=0), NoiseModel(), seed=3)
    d = diagnose(truth, drops, seed=3, **BUDGET)
    assert d.missing is None
    assert all(d.gain(r) < MIN_GAIN for r in d.results if r.fits)
    assert d.verdict().startswith("nothing missing")


def test_steps_error_falls_where_the_effect_is_added(truth, tmp_path):
    from slopelander.ident.diagnose import BUILTIN_CANDIDATES, Candidate
    from slopelander.ident.steps import run_steps

    drops = synthesize(truth, paper_drops(8, seed=0), NoiseModel(), seed=4, duration=0.6)
    base = truth.without("leg_flex")
    st = run_steps(
        base,
        drops,
        [Candidate("leg_flex", BUILTIN_CANDIDATES["leg_flex"])],
        seed=4,
        cma_evals=200,
        refit_evals=100,
    )
    assert [s.label for s in st.steps] == ["base", "+ leg_flex"]
    assert st.steps[1].validation < 0.8 * st.steps[0].validation
    assert st.steps[1].train < st.steps[0].train
    assert "| + leg_flex |" in st.table()
    assert st.plot(tmp_path / "steps.png").stat().st_size > 10_000


def test_hidden_torque_growth_is_found(model):
    """factor_tau at the paper's 5.8e-4 1/N changes these drops by less than the noise (see
    docs/ident.md), so the truth uses 5e-3 1/N."""
    truth = model.without("downhill_friction_growth").with_params(factor_tau=5e-3)
    drops = synthesize(truth, paper_drops(10, seed=0), NoiseModel(), seed=1)
    d = diagnose(truth.without("downhill_torque_growth"), drops, seed=1, **BUDGET)
    best = d.missing
    assert best is not None and best.candidate.name == "downhill_torque_growth", d.table()
    assert 1 - best.validation_nrmse / d.base_validation >= 0.30, d.table()
    assert best.values()["factor_tau"] == pytest.approx(5e-3, rel=0.15)


def test_hidden_friction_growth_at_the_paper_value_is_below_the_noise(model):
    """Since eq. 4 only raises the downhill foot's friction (max(1, 1 + factor_mu v), as the
    model's documentation says), factor_mu at the paper's 0.57 s/m changes these drops by less
    than the motion-capture noise: diagnose must say nothing is missing rather than invent a
    gain. (Before that fix most of eq. 4's signal came from feet sliding below mu_k, or with no
    friction at all; a proof that a visible factor_mu is found is open: docs/ident.md.)"""
    truth = model.without("downhill_torque_growth")
    drops = synthesize(truth, paper_drops(10, seed=0), NoiseModel(), seed=2)
    d = diagnose(truth.without("downhill_friction_growth"), drops, seed=2, **BUDGET)
    assert d.missing is None, d.table()
    row = next(r for r in d.results if r.candidate.name == "downhill_friction_growth")
    assert abs(1 - row.validation_nrmse / d.base_validation) < 0.10, d.table()
