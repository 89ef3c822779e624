"""The table writer: what it chooses, its margins, and that the companion's loader reads it."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander.controller.table import LookupTable
from slopelander.envelope.maps import preset_conditions
from slopelander.envelope.table import build_table, write_table
from slopelander.model import Outcome, simulate_batch

#: its tests share one built table (built): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("envelope/envelope_table")


@pytest.fixture(scope="module")
def built(model, tiny_axes, tmp_path_factory):
    doc, presets = build_table(model, tiny_axes, "rvt", progress=False, command="slopelander table")
    path = write_table(doc, tmp_path_factory.mktemp("table") / "table.yaml")
    return doc, presets, path


def test_the_written_table_loads_and_holds_the_chosen_presets(built):
    doc, presets, path = built
    t = LookupTable.load(path)
    for f in ("tau_up", "tau_down", "angle_up_deg", "angle_down_deg"):
        np.testing.assert_allclose(t.cells[f], presets.fields[f], atol=1e-4)
    names = [o.name.lower() for o in Outcome]
    assert [[names.index(x) for x in row] for row in t.cells["outcome"]] == presets.outcome.tolist()
    assert t.model["parameters"]["body_mass"]["value"] == 1.502
    assert "rotors" in t.model["effects"]
    assert t.strategy["reverse_percent"] == 100.0
    assert doc["generator"]["command"] == "slopelander table"


def test_margin_is_the_neighbourhood_success_of_the_cells_own_preset(built, model, tiny_axes):
    _, presets, _ = built
    i, j = 2, 1  # an interior cell
    base = preset_conditions(presets).reshape(tiny_axes.shape)[i, j]
    g = np.repeat(base[None], 9)
    g["slope_deg"] = np.repeat(tiny_axes.slopes[i - 1 : i + 2], 3)
    g["speed"] = np.tile(tiny_axes.speeds[j - 1 : j + 2], 3)
    ok = simulate_batch(g, model)["outcome"] <= Outcome.END_OF_TRAVEL
    expected = ok.mean() if presets.landed()[i, j] else 0.0
    assert presets.fields["margin"][i, j] == pytest.approx(expected)
    assert np.all(presets.fields["margin"][~presets.landed()] == 0.0)
    spare = 1 - np.maximum(presets.fields["compression_up"], presets.fields["compression_down"])
    np.testing.assert_allclose(presets.fields["spare_travel"], np.clip(spare, 0, 1))


def test_lookups_on_grid_points_return_the_written_cells(built, tiny_axes):
    _, presets, path = built
    t = LookupTable.load(path)
    p = t.lookup(float(tiny_axes.slopes[3]), float(tiny_axes.speeds[2]))
    assert p.cell == (3, 2)
    assert p.tau_up == pytest.approx(presets.fields["tau_up"][3, 2], abs=1e-4)


def test_any_lookup_inside_a_generated_table_stays_within_its_values(built):
    from hypothesis import given, settings
    from hypothesis import strategies as st

    t = LookupTable.load(built[2])
    (s0, s1), (v0, v1) = t.slope_range, t.speed_range

    @settings(max_examples=200, deadline=None)
    @given(st.floats(s0, s1), st.floats(v0, v1))
    def check(slope, speed):
        p = t.lookup(slope, speed)
        for f in ("tau_up", "tau_down", "angle_up_deg", "angle_down_deg"):
            assert t.cells[f].min() <= getattr(p, f) <= t.cells[f].max()

    check()


@pytest.mark.parametrize("strategy", ["rigid", "rigid_rvt"])
def test_no_table_for_the_stock_rigid_gear(model, tiny_axes, strategy):
    # its landings can be "damaged", which no table cell may hold, and it has no legs to set
    from slopelander.envelope.presets import StrategyError

    with pytest.raises(StrategyError, match="rigid gear"):
        build_table(model, tiny_axes, strategy, progress=False)


def test_the_rigid_map_shows_damaged_cells_and_fsa_maps_none(model, tiny_axes):
    # the structural limit is the stock gear's: fast or steep rigid landings break it, the FSA's never
    from slopelander.envelope.presets import choose_presets

    rigid = choose_presets(model, tiny_axes, "rigid", progress=False)
    fsa = choose_presets(model, tiny_axes, "asymmetric", progress=False)
    assert (rigid.outcome == Outcome.DAMAGED).sum() > rigid.outcome.size // 2
    assert (rigid.outcome == Outcome.IDEAL).any()
    assert not (fsa.outcome == Outcome.DAMAGED).any()
