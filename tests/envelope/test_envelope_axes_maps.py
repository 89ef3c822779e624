"""Map axes, the map container's files and the envelope figures of merit."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from slopelander.envelope.axes import AxesError, MapAxes
from slopelander.envelope.maps import (
    LandingMap,
    MapFileError,
    envelope_area,
    max_slope,
    reach_per_speed,
    summary,
)
from slopelander.model import OUTCOME_NAMES, Outcome


def test_default_axes_are_the_papers_range_at_1_deg_by_0_1_mps():
    ax = MapAxes.build()
    assert ax.shape == (61, 26)
    assert ax.slopes[[0, -1]].tolist() == [0.0, 60.0]
    assert ax.speeds[[0, -1]].tolist() == [0.5, 3.0]
    assert ax.speeds[2] == 0.7  # rounded grid values compare exactly
    assert ax.cell_area == pytest.approx(0.1)


@pytest.mark.parametrize(
    "kw", [{"slope_step": 0}, {"speed_step": -0.1}, {"slope_max": 80}, {"speed_min": 2.0, "speed_max": 1.0}]
)
def test_impossible_axes_are_refused(kw):
    with pytest.raises(AxesError):
        MapAxes.build(**kw)


def synthetic_map() -> LandingMap:
    ax = MapAxes(np.array([0.0, 10.0, 20.0, 30.0]), np.array([1.0, 2.0]))
    o = np.array(
        [
            [Outcome.IDEAL, Outcome.UNDER_USED],
            [Outcome.IDEAL, Outcome.IDEAL],
            [Outcome.FLIP, Outcome.END_OF_TRAVEL],
            [Outcome.IDEAL, Outcome.SLID],
        ],
        float,
    )
    f = {
        "outcome": o,
        "tau_up": np.full(o.shape, 1.1),
        "tau_down": np.full(o.shape, 2.3),
        "angle_up_deg": np.full(o.shape, 30.0),
        "angle_down_deg": np.full(o.shape, 37.5),
        "settle_time": np.where(o > 2, np.nan, 0.5),
    }
    return LandingMap("synthetic", ax, f, {"description": "test"})


def test_figures_of_merit_follow_their_definitions():
    m = synthetic_map()
    assert envelope_area(m, "ideal") == pytest.approx(4 * 10.0 * 1.0)
    assert envelope_area(m, "landed") == pytest.approx(6 * 10.0)
    assert max_slope(m, "ideal") == 30.0  # the isolated ideal cell past a flip counts
    assert reach_per_speed(m, "ideal").tolist()[0] == 10.0  # ...but not for the unbroken reach
    assert np.isnan(reach_per_speed(m, "ideal")[1])  # first slope under-used: no reach
    assert reach_per_speed(m, "landed").tolist() == [10.0, 20.0]
    s = summary(m)
    assert s["reach_landed_min_deg"] == 10.0 and s["reach_landed_max_deg"] == 20.0
    counts = {o: s[f"cells_{o}"] for o in OUTCOME_NAMES}
    assert sum(counts.values()) == m.outcome.size and counts["damaged"] == 0
    assert counts["flip"] == int((m.outcome == Outcome.FLIP).sum()) > 0


def test_a_map_round_trips_through_npz_and_writes_one_csv_row_per_cell(tmp_path):
    m = synthetic_map()
    npz, path_csv = m.save(tmp_path)
    back = LandingMap.load(npz)
    assert back.kind == "synthetic" and back.meta == {"description": "test"}
    for k, v in m.fields.items():
        np.testing.assert_array_equal(back.fields[k], v)
    rows = list(csv.DictReader(path_csv.open()))
    assert len(rows) == 8
    assert rows[4]["slope_deg"] == "20" and rows[4]["outcome_name"] == "flip"
    assert rows[4]["settle_time"] == ""  # NaN is an empty CSV cell


def test_a_file_that_is_not_a_map_is_refused(tmp_path):
    p = tmp_path / "x.npz"
    np.savez(p, a=np.zeros(2))
    with pytest.raises(MapFileError, match="not a landing map"):
        LandingMap.load(p)
