"""Gaps in recordings (empty cells, NaN in memory): kept on disk, left out of every error."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from slopelander.ident.compare import compare, state_ranges
from slopelander.ident.evidence import noise_floor
from slopelander.ident.fit import Problem, resolve_params
from slopelander.ident.mocap.rates import describe, savgol_rates
from slopelander.ident.recording import RecordingError, load_drop, write_drop
from slopelander.ident.synth import NoiseModel, synthesize
from slopelander.model import LandingConditions

#: its tests share one dataset (drops): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("ident/gaps")


@pytest.fixture(scope="module")
def drops(model):
    conds = [LandingConditions(slope_deg=15.0, speed=2.0), LandingConditions(slope_deg=30.0, speed=2.5)]
    out = []
    for d in synthesize(model, conds, NoiseModel(sample_rate=200.0), seed=3, duration=0.4):
        pos = d.states[:, :3].copy()
        pos[30:36] = np.nan  # 30 ms not seen, after contact
        rates = savgol_rates(pos, 0.005, 7, 2)
        meta = {**d.meta, "rates": describe(7, 2, 0.005)}
        out.append(replace(d, states=np.column_stack([pos, rates]), meta=meta))
    return out


def test_gaps_round_trip_as_empty_cells(tmp_path, drops):
    path = write_drop(drops[0], tmp_path)
    row = path.read_text().splitlines()[31]  # header is line 1: sample 30
    assert row.split(",")[1:] == ["", "", "", "", "", ""]
    back = load_drop(path)
    assert np.array_equal(np.isnan(back.states), np.isnan(drops[0].states))
    assert back.savgol == (7, 2, 0.005)


def test_an_empty_time_is_not_a_gap(tmp_path, drops):
    path = write_drop(drops[0], tmp_path)
    lines = path.read_text().splitlines()
    lines[5] = "," + lines[5].split(",", 1)[1]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match="line 6, field 'time'"):
        load_drop(path)


def test_a_missing_row_under_savgol_rates_is_refused(tmp_path, drops):
    path = write_drop(drops[0], tmp_path)
    lines = path.read_text().splitlines()
    del lines[40]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match=r"field 'time'.*not one frame"):
        load_drop(path)


def test_the_fit_leaves_gaps_out(model, drops):
    ranges = state_ranges(drops)
    prob = Problem(model, drops, resolve_params(model, ["ground_damping"]), ranges)
    r = prob.residuals([0.5])
    seen = sum(int(np.isfinite(d.states[d.t >= 0]).sum()) for d in drops)
    assert len(r) == prob.size == len(prob.groups()) == seen
    assert np.isfinite(r).all() and not (r == 10.0).any()  # no gap became a penalty
    # its sum of squares is the weighted mean of the states' squared NRMSE, as compare's
    at = prob.model_at([0.5])
    c = compare(at, drops, ranges)
    w = np.array([1.0, 1, 2, 1, 1, 2])
    expect = np.mean([np.sum(w * d.per_state**2) / w.sum() for d in c.drops])
    assert float(r @ r) == pytest.approx(expect, rel=1e-9)


def test_the_noise_floor_with_gaps_and_savgol_rates(model, drops):
    floor = noise_floor(model, drops, state_ranges(drops))
    assert floor is not None and np.isfinite(floor) and floor > 0
