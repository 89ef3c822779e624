"""First contact from foot markers: takes of the truth simulator with a marker on each foot,
imported with the markers file's ``feet``; the contact time against the truth's own."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander.ident.mocap.importer import import_takes
from slopelander.ident.mocap.markerset import load_markerset
from slopelander.ident.mocap.take import MocapError
from slopelander.ident.recording import load_drop
from slopelander.ident.truth.lab import EXAMPLE, foot_offsets, frame_times, observe, write_take
from slopelander.ident.truth.physics import truth_states
from slopelander.model import LandingConditions, Model

#: its tests share the imported takes (a module fixture): one worker runs them
pytestmark = pytest.mark.xdist_group("ident/test_import_feet")

MARKERS = """\
schema: slopelander.markers/1
units: mm
body:
  markers:
    FR_ARM: [120, -45, 30]
    FL_ARM: [110, 60, 25]
    REAR: [-125, 10, 35]
    TOP: [10, -20, 90]
roof:
  markers: [ROOF1, ROOF2, ROOF3, ROOF4]
  marker_height: 7
feet:
  markers: [FOOT_C, FOOT_D]
  marker_height: 10
keep: {before_s: 0.1, after_s: 0.2}
conditions: {tau_up: 1.1, tau_down: 1.7}
"""
TAKES = 8


@pytest.fixture(scope="module")
def feet_takes(tmp_path_factory):
    """Eight takes of one landing (22 deg, 2 m/s) at new frame phases and marker noise: the
    true contact time in each take's clock, and the imported drops."""
    model = Model.default()
    cond = LandingConditions(slope_deg=22.0, speed=2.0, tau_up=1.1, tau_down=1.7)
    grid = np.arange(-0.16, 0.31, 1 / 4000)
    dense, _ = truth_states(model, cond, grid)
    feet = foot_offsets(model, cond)
    folder = tmp_path_factory.mktemp("feet")
    (folder / "markers.yaml").write_text(MARKERS)
    rng = np.random.default_rng(11)
    true_tc = {}
    for i in range(TAKES):
        t = frame_times(rng, 200.0, 0.15, 0.3)
        states = np.column_stack([np.interp(t, grid, dense[:, c]) for c in range(3)])
        lab = EXAMPLE[f"drop0{1 + i % 6}"][1]  # drop07 lands yawed: not planar
        labels, pts = observe(states, t, cond.slope_deg, lab, rng, feet=feet)
        write_take(folder / f"take{i}.c3d", labels, pts, 200.0)
        true_tc[f"take{i}"] = -t[0]  # the take's clock starts at its first frame
    out = folder / "drops"
    report = import_takes([folder / f"take{i}.c3d" for i in range(TAKES)], folder / "markers.yaml", out)
    return true_tc, out, report


def test_first_contact_from_foot_markers_is_the_truths(feet_takes):
    """Within 1 ms of the true contact in every take (frames 5 ms apart), no bias beyond
    0.5 ms, and the printed +- (68 %) covers the error about as often as it says."""
    true_tc, out, report = feet_takes
    err, sd = [], []
    for name, tc in true_tc.items():
        q = load_drop(out / f"{name}.csv").meta["quality"]
        assert q["contact_from"] == "foot marker FOOT_C" or q["contact_from"] == "foot marker FOOT_D"
        err.append(q["contact_time_in_take_s"] - tc)
        sd.append(q["contact_sd_s"])
    err, sd = np.array(err), np.array(sd)
    assert np.abs(err).max() < 1e-3, err
    assert abs(err.mean()) < 5e-4, err
    assert (np.abs(err) <= 2 * sd).mean() >= 0.75, (err, sd)
    assert "(foot marker FOOT_" in report[0].lines[0]


def test_foot_markers_are_named_and_checked(tmp_path, feet_takes):
    _, out, _ = feet_takes
    src = out.parent
    bad = tmp_path / "markers.yaml"
    bad.write_text(MARKERS.replace("FOOT_D]", "FOOT_X]"))
    with pytest.raises(MocapError, match=r"feet\.markers\.FOOT_X"):
        import_takes([src / "take0.c3d"], bad, tmp_path / "o1")
    bad.write_text(MARKERS.replace("  marker_height: 10\n", ""))
    with pytest.raises(MocapError, match=r"feet\.marker_height.*missing"):
        load_markerset(bad)
    # a marker height 70 mm too high puts the touch 35 ms before the body decelerates
    bad.write_text(MARKERS.replace("marker_height: 10", "marker_height: 80"))
    with pytest.raises(MocapError, match=r"feet\.marker_height.*decelerates"):
        import_takes([src / "take0.c3d"], bad, tmp_path / "o2")
    assert not (tmp_path / "o1").exists() and not (tmp_path / "o2").exists()
