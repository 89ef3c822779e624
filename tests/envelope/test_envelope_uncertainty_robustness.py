"""Parameter sets standing in for the paper's three GA fits, and the attitude robustness map."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander.envelope.axes import MapAxes
from slopelander.envelope.presets import choose_presets
from slopelander.envelope.robustness import robustness_map
from slopelander.envelope.uncertainty import (
    TABLE_II_SIGMA,
    parameter_sets,
    success_fraction,
    uncertainty_maps,
    write_parameter_sets,
)
from slopelander.model import ModelParams, Outcome

#: its tests share one small sweep (two_by_two): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("envelope/envelope_uncertainty_robustness")


def test_sets_reproduce_table_ii_mean_and_sigma_exactly(model):
    sets = parameter_sets(model.params, 3, seed=0)
    for name, sigma in TABLE_II_SIGMA.items():
        v = np.array([p[name] for p in sets])
        assert v.mean() == pytest.approx(model.params[name])
        assert v.std(ddof=1) == pytest.approx(sigma)
    untouched = [n for n in ("body_mass", "friction_static", "rotor_thrust_max")]
    assert all(p[n] == model.params[n] for p in sets for n in untouched)


def test_no_set_is_low_or_high_on_every_parameter(model):
    sets = parameter_sets(model.params, 3, seed=0)
    for p in sets:
        signs = {np.sign(p[n] - model.params[n]) for n in TABLE_II_SIGMA}
        assert len(signs) > 1


def test_sets_are_written_as_derived_parameter_files(model, tmp_path):
    paths = write_parameter_sets(parameter_sets(model.params, 3), tmp_path)
    assert [p.name for p in paths] == ["params_set1.yaml", "params_set2.yaml", "params_set3.yaml"]
    loaded = ModelParams.load(paths[1])
    assert loaded.values["flex_stiffness"].provenance == "derived"
    assert "Table II" in loaded.values["flex_stiffness"].note


@pytest.fixture(scope="module")
def two_by_two(tiny_axes):
    return MapAxes(tiny_axes.slopes[1:3], tiny_axes.speeds[1:3])


def test_uncertainty_flies_one_set_of_presets_with_every_parameter_set(model, two_by_two):
    sets = parameter_sets(model.params, 3)
    nominal, maps = uncertainty_maps(model, two_by_two, "asymmetric", sets, progress=False)
    assert len(maps) == 3
    for m, p in zip(maps, sets, strict=False):
        np.testing.assert_array_equal(m.fields["tau_up"], nominal.fields["tau_up"])
        assert m.meta["model"]["parameters"]["flex_stiffness"]["value"] == p["flex_stiffness"]
    frac = success_fraction(maps)
    assert frac.shape == two_by_two.shape and np.all((frac >= 0) & (frac <= 1))


def test_robustness_rate_is_the_share_of_draws_that_land(model, two_by_two):
    presets = choose_presets(model, two_by_two, "rvt", progress=False)
    r = robustness_map(presets, model, draws=3, seed=1, progress=False)
    again = robustness_map(presets, model, draws=3, seed=1, progress=False)
    np.testing.assert_array_equal(r.fields["success_rate"], again.fields["success_rate"])
    assert set(np.unique(np.round(r.fields["success_rate"] * 3)).tolist()) <= {0, 1, 2, 3}
    nominal = presets.outcome <= Outcome.END_OF_TRAVEL
    np.testing.assert_array_equal(r.fields["nominal"] > 0, nominal)
    assert nominal.any(), "the grid must hold landed cells for the rate to mean anything"
    assert r.meta["overall"] == pytest.approx(r.fields["success_rate"][nominal].mean())
    assert r.meta["landings"] == two_by_two.size * 3
