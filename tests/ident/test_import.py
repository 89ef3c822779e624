"""slopelander import: raw motion-capture takes in, drops out, checked against the truth the
shipped takes were made from (docs/examples/mocap, made by ident.truth.lab)."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from slopelander.ident.compare import compare
from slopelander.ident.mocap.formats import read_c3d, read_take
from slopelander.ident.mocap.importer import import_takes
from slopelander.ident.mocap.pose import fit_cluster
from slopelander.ident.mocap.rates import savgol_rates
from slopelander.ident.observe import predict
from slopelander.ident.recording import load_dataset, load_drop
from tests.ident.mocap_files import motive_csv, qualisys_tsv, vicon_csv

#: its tests share one imported take (imported, marker_take): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("ident/import")

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "mocap"
MARKERS = EXAMPLE / "markers.yaml"
BODY = np.array([[120, -45, 30], [110, 60, 25], [-125, 10, 35], [10, -20, 90]]) / 1000.0


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("imp") / "drops"
    import_takes([EXAMPLE], MARKERS, out)
    return out


def test_the_shipped_takes_are_small_real_c3d_files():
    ezc3d = pytest.importorskip("ezc3d")
    for path in sorted(EXAMPLE.glob("*.c3d")):
        assert path.stat().st_size < 40_000
        ours = read_c3d(path)
        theirs = ezc3d.c3d(str(path))
        pts = (
            np.moveaxis(theirs["data"]["points"][:3], 0, 2).transpose(1, 0, 2) / 1000.0
        )  # frames, markers, 3
        assert theirs["parameters"]["POINT"]["UNITS"]["value"] == ["mm"]
        assert theirs["parameters"]["POINT"]["RATE"]["value"][0] == ours.rate == 200.0
        assert list(theirs["parameters"]["POINT"]["LABELS"]["value"]) == list(ours.labels)
        seen = np.isfinite(ours.xyz)
        assert np.array_equal(seen, np.isfinite(pts)), path.name  # gaps are gaps in both
        assert np.allclose(ours.xyz[seen], pts[seen], atol=1e-9)


def test_import_gets_the_truth_back(imported):
    """Positions within the marker noise, slope and impact speed within 0.3 deg / 3 %, first
    contact within 3 ms of the truth's (frame spacing 5 ms)."""
    truth = {d.name: d for d in load_dataset(EXAMPLE / "truth")}
    for d in load_dataset(imported):
        tr = truth[d.name]
        tc_true = -tr.t[0] + 0.0  # the truth's frames: 0 = the true contact
        tc = d.meta["quality"]["contact_time_in_take_s"]
        # the take's first frame is the truth's first frame
        first = round((d.t[0] + tc) * 200.0)
        ref = tr.states[first : first + len(d.t)]
        assert abs(tc - tc_true) < 0.003, d.name
        err = d.states[:, :3] - ref[:, :3]
        assert np.sqrt(np.nanmean(err[:, 0] ** 2)) < 1e-3 and np.sqrt(np.nanmean(err[:, 1] ** 2)) < 1e-3
        assert math.degrees(np.sqrt(np.nanmean(err[:, 2] ** 2))) < 0.3
        assert abs(d.conditions.slope_deg - tr.conditions.slope_deg) < 0.3
        assert abs(d.conditions.speed - tr.conditions.speed) < 0.03 * tr.conditions.speed
        assert (d.conditions.tau_up, d.conditions.tau_down) == (tr.conditions.tau_up, tr.conditions.tau_down)


def test_each_drop_carries_its_provenance_rates_and_noise(imported):
    d = load_drop(imported / "drop02.csv")
    prov = d.meta["provenance"]
    assert prov["file"] == "drop02.c3d" and prov["format"] == "C3D" and len(prov["sha256"]) == 64
    assert prov["body"] == ["FR_ARM", "FL_ARM", "REAR", "TOP"] and prov["up"].startswith(
        "+Z (POINT:Y_SCREEN)"
    )
    rates = d.meta["rates"]
    assert rates["method"] == "savgol" and rates["window"] == 7 and rates["lag_s"] == 0.0
    assert 10.0 < rates["bandwidth_hz"] < 30.0
    # the lab model's markers jitter 0.5 mm per axis; four markers: 0.25 mm for the centre
    assert d.meta["noise"]["marker_sd_m"] == pytest.approx(5e-4, rel=0.1)
    assert d.meta["noise"]["position_sd_m"] == pytest.approx(2.5e-4, rel=0.1)
    q = d.meta["quality"]
    assert q["planar"] and q["rate_hz"] == 200.0 and q["gaps"] == []  # three markers still give a pose


def test_gaps_stay_gaps_and_are_masked(imported):
    """drop03 loses two of its four markers for 25 ms: no pose there, no rate across it."""
    d = load_drop(imported / "drop03.csv")
    gap = ~np.isfinite(d.states[:, 0])
    assert 4 <= gap.sum() <= 6 and d.meta["quality"]["gaps"][0]["frames"] == int(gap.sum())
    first = int(np.flatnonzero(gap)[0])
    rate_gap = ~np.isfinite(d.states[:, 3])
    assert rate_gap[first - 3 : first + gap.sum() + 3].all()  # every window touching it
    assert np.isfinite(d.states[first - 1, :3]).all()
    from slopelander.model import Model

    model = Model.default()
    full = compare(model, [d]).drops[0]
    assert np.isfinite(full.per_state).all()
    # the same as leaving the gap's samples out by hand (at the lag compare aligned the take to:
    # an imported take's clock is fitted within its contact interval, docs/ident.md "Clocks")
    assert 0 < abs(full.lag) <= 3 * d.meta["quality"]["contact_sd_s"]
    sim, _ = predict(model, d, outcome=False, lag=full.lag)
    err = (sim - d.states)[d.t >= 0] / compare(model, [d]).ranges
    ok = np.isfinite(err)
    by_hand = np.sqrt([np.mean(err[ok[:, i], i] ** 2) for i in range(6)])
    assert np.allclose(full.per_state, by_hand)


def test_the_model_is_smoothed_as_the_take_was(imported):
    from slopelander.model import Model

    d = load_drop(imported / "drop01.csv")
    sim, _ = predict(Model.default(), d, outcome=False)
    assert np.allclose(sim[:, 3:], savgol_rates(sim[:, :3], 0.005, 7, 2), equal_nan=True)


def test_a_take_out_of_the_landing_plane_is_flagged_not_flattened(imported):
    assert not (imported / "drop07.csv").exists()
    d = load_drop(imported / "not-planar" / "drop07.csv")
    assert not d.meta["quality"]["planar"] and d.meta["quality"]["yaw_deg"] == pytest.approx(8.0, abs=0.8)


@pytest.fixture(scope="module")
def marker_take():
    return read_take(EXAMPLE / "drop02.c3d")


@pytest.mark.parametrize("fmt", ["vicon", "qualisys", "motive"])
def test_every_exporter_layout_gives_the_same_drop(tmp_path, imported, marker_take, fmt):
    tk = marker_take
    labels = list(tk.labels)
    src = tmp_path / "takes"
    src.mkdir()
    if fmt == "vicon":
        vicon_csv(src / "drop02.csv", labels, tk.xyz, tk.rate)
    elif fmt == "qualisys":
        qualisys_tsv(src / "drop02.tsv", labels, tk.xyz, tk.rate)
    else:
        motive_csv(src / "drop02.csv", labels, tk.xyz, tk.rate, units="Millimeters")
    shutil.copy(EXAMPLE / "takes.csv", tmp_path / "takes.csv")
    markers = tmp_path / "markers.yaml"
    text = MARKERS.read_text().replace("takes: takes.csv", "takes: takes.csv\nup_axis: +Z")
    markers.write_text(text)
    import_takes([src], markers, tmp_path / "out")
    got = load_drop(tmp_path / "out" / "drop02.csv")
    ref = load_drop(imported / "drop02.csv")
    diff = np.abs(got.states - ref.states)
    assert np.allclose(got.t, ref.t), np.nanmax(diff, axis=0)
    # the same drop to far below the noise (0.25 mm, 0.14 deg): the text formats round the floats
    tol = np.array([1e-5, 1e-5, 1e-4, 1e-3, 1e-3, 1e-2])
    assert (np.nan_to_num(diff) <= tol).all(), np.nanmax(diff, axis=0)
    assert np.array_equal(np.isnan(got.states), np.isnan(ref.states))
    assert got.conditions == ref.conditions


def test_a_motive_rigid_body_in_y_up_axes(tmp_path, imported, marker_take):
    """Motive's own solved rigid body, exported Y-up (Motive's default) and not saying so: the
    vertical comes from the free fall, the pose from the rigid body's quaternions."""
    from scipy.spatial.transform import Rotation

    tk = marker_take
    fit = fit_cluster(tk.xyz[:, :4], BODY)
    to_yup = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # (X, Y, Z) Z-up -> (X, Z, -Y)
    local = np.column_stack([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # body x, y, z in the rigid body's axes
    pivot = np.array([0.01, 0.0, 0.04])  # m, body frame: where Motive put the rigid body's pivot
    ok = np.isfinite(fit.position[:, 0])
    rot = np.einsum("ij,fjk,lk->fil", to_yup, fit.rotation[ok], local)  # rigid-body axes -> Y-up
    quat = np.full((tk.frames, 4), np.nan)
    quat[ok] = Rotation.from_matrix(rot).as_quat()
    pos = np.full((tk.frames, 3), np.nan)
    pos[ok] = (fit.position[ok] + np.einsum("fij,j->fi", fit.rotation[ok], pivot)) @ to_yup.T
    src = tmp_path / "drop02.csv"
    motive_csv(src, [], np.zeros((tk.frames, 0, 3)), tk.rate, body=("quad", quat, pos))
    roof = tmp_path / "roof.csv"  # the roof markers, exported alone
    motive_csv(roof, list(tk.labels[4:]), tk.xyz[:, 4:] @ to_yup.T, tk.rate)
    # one file with both: the rigid body's columns, then the roof markers'
    body_rows = src.read_text().splitlines()
    roof_rows = roof.read_text().splitlines()
    merged = body_rows[:2] + [
        b + "," + ",".join(r.split(",")[2:]) for b, r in zip(body_rows[2:], roof_rows[2:], strict=True)
    ]
    src.write_text("\n".join(merged) + "\n")
    roof.unlink()
    shutil.copy(EXAMPLE / "takes.csv", tmp_path / "takes.csv")
    markers = tmp_path / "markers.yaml"
    text = MARKERS.read_text()
    start, end = text.index("body:"), text.index("roof:")
    markers.write_text(
        text[:start]
        + "body:\n  rigid_body: quad\n  centre_of_mass: [-10, -40, 0]  # mm, in the rigid body's axes\n"
        + "  forward: +X\n  up: +Y\n"
        + text[end:]
    )
    import_takes([tmp_path / "drop02.csv"], markers, tmp_path / "out")
    got = load_drop(tmp_path / "out" / "drop02.csv")
    ref = load_drop(imported / "drop02.csv")
    assert "measured: the free fall" in got.meta["provenance"]["up"] and got.meta["provenance"][
        "up"
    ].startswith("+Y")
    assert np.allclose(got.states[:, :3], ref.states[:, :3], atol=2e-5, equal_nan=True)
    assert got.conditions.slope_deg == pytest.approx(ref.conditions.slope_deg, abs=0.02)
    assert got.meta["noise"]["method"] == "free-flight residuals"
    assert got.meta["noise"]["position_sd_m"] == pytest.approx(2.5e-4, rel=0.5)
