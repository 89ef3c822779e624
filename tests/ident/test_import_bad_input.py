"""slopelander import on bad input: one line naming the file, the take and the field, before
any take is solved, and nothing in (or beside) the output folder. A real process each."""

from __future__ import annotations

import copy
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from slopelander.ident.mocap.formats import read_take, write_c3d
from slopelander.ident.mocap.markerset import load_markerset
from slopelander.ident.mocap.take import MocapError
from tests.ident.mocap_files import motive_csv, qualisys_tsv, vicon_csv

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "mocap"


def run_import(folder: Path, *takes: str, markers: str = "markers.yaml") -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}"}
    return subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "import", *takes, "--markers", markers, "--out", "out"],
        capture_output=True,
        text=True,
        env=env,
        cwd=folder,
        timeout=120,
    )


@pytest.fixture
def lab(tmp_path) -> Path:
    """A copy of the shipped example: takes, markers file, takes table."""
    for p in EXAMPLE.iterdir():
        if p.is_file():
            shutil.copy(p, tmp_path / p.name)
    return tmp_path


def assert_refused(r: subprocess.CompletedProcess, folder: Path, *words: str) -> str:
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("slopelander import: error: "), r.stderr
    for w in words:
        assert w in lines[0], lines[0]
    assert not (folder / "out").exists()
    assert not [p for p in folder.iterdir() if p.name.startswith(".out")]  # no half-written folder beside it
    return lines[0]


def test_a_truncated_c3d_among_good_takes_writes_nothing(lab):
    data = (lab / "drop07.c3d").read_bytes()
    (lab / "drop07.c3d").write_bytes(data[: len(data) // 2])
    assert_refused(run_import(lab, "."), lab, "drop07.c3d", "take 'drop07'", "field '<data>'", "truncated")


def test_a_file_that_is_not_c3d(lab):
    (lab / "notes.c3d").write_text("take 4 was bad, the roof moved\n")
    assert_refused(run_import(lab, "notes.c3d"), lab, "notes.c3d", "field '<header>'", "not a C3D file")


def test_a_csv_from_another_exporter(lab):
    (lab / "take.csv").write_text(
        "PathFileType,4,(X/Y/Z),take.trc\nDataRate,CameraRate,NumFrames\n200,200,140\n"
    )
    assert_refused(
        run_import(lab, "take.csv"), lab, "take.csv", "field '<format>'", "Vicon Nexus", "OptiTrack Motive"
    )


def test_a_marker_the_markers_file_names_is_not_in_the_take(lab):
    text = (lab / "markers.yaml").read_text().replace("TOP: [", "TOPP: [")
    (lab / "markers.yaml").write_text(text)
    assert_refused(
        run_import(lab, "drop01.c3d"), lab, "drop01.c3d", "field 'body.markers.TOPP'", "closest: TOP"
    )


def test_a_marker_renamed_in_the_export(lab):
    tk = read_take(lab / "drop01.c3d")
    labels = [("HEAD" if m == "TOP" else m) for m in tk.labels]
    vicon_csv(lab / "drop01.csv", labels, tk.xyz, tk.rate)
    line = assert_refused(run_import(lab, "drop01.csv"), lab, "drop01.csv", "field 'body.markers.TOP'")
    assert "no marker 'TOP'" in line


def test_a_cluster_that_is_not_rigid(lab):
    tk = read_take(lab / "drop01.c3d")
    xyz = tk.xyz.copy()
    i = tk.labels.index("TOP")
    xyz[:, i, 0] += np.linspace(0.0, 0.03, tk.frames)  # the marker slides 30 mm along the frame
    write_c3d(lab / "drop01.c3d", list(tk.labels), xyz, tk.rate)
    assert_refused(
        run_import(lab, "drop01.c3d"), lab, "drop01.c3d", "field 'body.markers'", "not rigid", "TOP"
    )


def test_lengths_in_another_unit_than_the_file_says(lab):
    """Millimetre numbers under POINT:UNITS 'm': a 1.5 km drop."""
    tk = read_take(lab / "drop01.c3d")
    write_c3d(lab / "drop01.c3d", list(tk.labels), tk.xyz * 1000.0, tk.rate, units="m")
    assert_refused(
        run_import(lab, "drop01.c3d"), lab, "drop01.c3d", "field 'POINT:UNITS'", "not in that unit"
    )


def test_a_take_that_ends_at_contact(lab):
    tk = read_take(lab / "drop01.c3d")
    keep = int(0.18 * tk.rate)  # contact is at 0.15 s
    write_c3d(lab / "drop01.c3d", list(tk.labels), tk.xyz[:keep], tk.rate)
    assert_refused(run_import(lab, "drop01.c3d"), lab, "drop01.c3d", "too little data", "after contact")


def test_a_rates_window_longer_than_the_take_after_contact(lab):
    """A 1 s window over 0.5 s kept after contact: every rate would be a gap. Before, the take was
    imported with no rate at all."""
    text = (lab / "markers.yaml").read_text() + "rates: {window_s: 1.0, polyorder: 2}\n"
    (lab / "markers.yaml").write_text(text)
    assert_refused(
        run_import(lab, "drop01.c3d"), lab, "drop01.c3d", "field 'rates.window_s'", "longer than the", "kept"
    )


def test_a_take_that_starts_on_the_roof(lab):
    tk = read_take(lab / "drop01.c3d")
    write_c3d(lab / "drop01.c3d", list(tk.labels), tk.xyz[int(0.2 * tk.rate) :], tk.rate)
    assert_refused(run_import(lab, "drop01.c3d"), lab, "drop01.c3d", "does not start in free fall")


def test_a_condition_the_take_measures_itself(lab):
    (lab / "markers.yaml").write_text((lab / "markers.yaml").read_text() + "conditions: {slope_deg: 20}\n")
    assert_refused(
        run_import(lab, "drop01.c3d"), lab, "markers.yaml", "field 'conditions.slope_deg'", "measured"
    )


def test_an_output_folder_that_holds_something(lab):
    (lab / "out").mkdir()
    (lab / "out" / "drop01.csv").write_text("time [s]\n")
    r = run_import(lab, "drop01.c3d")
    assert r.returncode == 1 and "not an empty folder" in r.stderr
    assert [p.name for p in (lab / "out").iterdir()] == ["drop01.csv"]


@pytest.mark.parametrize(
    ("edit", "field", "words"),
    [
        (lambda t: t.replace("units: mm ", "units: inch "), "units", "say the unit"),
        (lambda t: t.replace("keep:", "kept:"), "kept", "unknown key"),
        (
            lambda t: t.replace("    REAR: [-125, 10, 35]\n    TOP: [10, -20, 90]\n", ""),
            "body.markers",
            "at least 3",
        ),
        (
            lambda t: (
                t.replace("[110, 60, 25]", "[0, 0, 0]")
                .replace("[-125, 10, 35]", "[-120, 45, -30]")
                .replace("[10, -20, 90]", "[240, -90, 60]")
            ),
            "body.markers",
            "on one line",
        ),
        (
            lambda t: t.replace("takes: takes.csv", "takes: {drop01.c3d: {tau_up: fast}}"),
            "takes.drop01.c3d.tau_up",
            "not a number",
        ),
        (lambda t: t.replace("units: mm ", "units: {mm: 1} "), "units", "{'mm': 1}: say the unit"),
        (lambda t: t.replace("units: mm ", "units: [mm] "), "units", "['mm']: say the unit"),
        (
            lambda t: t.replace("keep: {before_s: 0.1, after_s: 0.5}", "keep: [0.1, 0.5]"),
            "keep",
            "must be a mapping of after_s, before_s, got [0.1, 0.5]",
        ),
        (lambda t: t + "rates: 3\n", "rates", "must be a mapping of polyorder, window_s, got 3"),
        (lambda t: t + "planarity: 0.02\n", "planarity", "must be a mapping of lateral, roll_deg, yaw_deg"),
        (lambda t: t + "rates: {polyorder: 2.5}\n", "rates.polyorder", "2.5 is not a whole number"),
        (lambda t: t + "latency_s: 1" + "0" * 400 + "\n", "latency_s", "is not a number"),
        (
            lambda t: t.replace("[ROOF1, ROOF2, ROOF3, ROOF4]", "[ROOF1, {a: 1}, ROOF3, ROOF4]"),
            "roof.markers[1]",
            "{'a': 1} is not a name",
        ),
        (
            lambda t: t[: t.index("body:")] + "body: [FR_ARM, TOP]\n" + t[t.index("roof:") :],
            "body",
            "must be a mapping",
        ),
    ],
)
def test_a_markers_file_that_cannot_be_used(lab, edit, field, words):
    (lab / "markers.yaml").write_text(edit((lab / "markers.yaml").read_text()))
    assert_refused(run_import(lab, "drop01.c3d"), lab, "markers.yaml", f"field '{field}'", words)


def test_a_takes_table_with_a_bad_cell(lab):
    (lab / "takes.csv").write_text("take,tau_up,tau_down\ndrop01.c3d,1.1,strong\n")
    assert_refused(
        run_import(lab, "drop01.c3d"), lab, "takes.csv", "field 'line 2, tau_down'", "not a number"
    )


def test_a_motive_rigid_body_exported_with_euler_angles(lab):
    tk = read_take(lab / "drop01.c3d")
    motive_csv(lab / "drop01.csv", list(tk.labels), tk.xyz, tk.rate)
    rows = (lab / "drop01.csv").read_text().splitlines()
    rows[0] = rows[0].replace("Rotation Type,Quaternion", "Rotation Type,XYZ")
    rows[2] += ",Rigid Body,Rigid Body,Rigid Body"
    rows[3] += ",quad,quad,quad"
    rows[4] += ",1,1,1"
    rows[5] += ",Rotation,Rotation,Rotation"
    rows[6] += ",X,Y,Z"
    rows[7:] = [r + ",0,0,0" for r in rows[7:]]
    (lab / "drop01.csv").write_text("\n".join(rows) + "\n")
    text = (lab / "markers.yaml").read_text()
    start, end = text.index("body:"), text.index("roof:")
    (lab / "markers.yaml").write_text(text[:start] + "body:\n  rigid_body: quad\n" + text[end:])
    assert_refused(
        run_import(lab, "drop01.csv"), lab, "drop01.csv", "field 'body.rigid_body'", "export quaternions"
    )


def _drop_motive_column(path: Path, marker: str, axis: str) -> None:
    """The Motive export without one Position column of ``marker`` (every row under the
    key/value first line loses that cell)."""
    lines = path.read_text().splitlines()
    rows = [r.split(",") for r in lines[2:]]
    j = next(j for j in range(len(rows[4])) if rows[1][j] == marker and rows[4][j] == axis)
    path.write_text("\n".join(lines[:2] + [",".join(r[:j] + r[j + 1 :]) for r in rows]) + "\n")


def test_a_motive_marker_without_its_z_column(lab):
    tk = read_take(lab / "drop01.c3d")
    motive_csv(lab / "drop01.csv", list(tk.labels), tk.xyz, tk.rate)
    _drop_motive_column(lab / "drop01.csv", "TOP", "Z")
    line = assert_refused(
        run_import(lab, "drop01.csv"), lab, "drop01.csv", "take 'drop01'", "field 'TOP Position'"
    )
    assert "expected one X, Y and Z column, found 2 (X, Y)" in line


@pytest.mark.parametrize(
    ("edit", "field", "words"),
    [
        (lambda rows: rows, None, None),  # the file as Motive writes it reads
        (lambda rows: [r[:-1] for r in rows], "B Position", "found 2 (X, Y)"),
        (lambda rows: [[*r, r[-1]] for r in rows], "B Position", "found 4 (X, Y, Z, Z)"),
        (lambda rows: [[*r[:-2], r[-1], r[-1]] for r in rows], "B Position", "found 3 (X, Z, Z)"),
    ],
)
def test_a_motive_marker_with_other_than_three_position_columns(tmp_path, edit, field, words):
    xyz = np.arange(10 * 2 * 3, dtype=float).reshape(10, 2, 3)
    path = tmp_path / "take.csv"
    motive_csv(path, ["A", "B"], xyz, 100.0)
    lines = path.read_text().splitlines()
    rows = [r.split(",") for r in lines[2:]]
    path.write_text("\n".join(lines[:2] + [",".join(r) for r in edit(rows)]) + "\n")
    if field is None:
        np.testing.assert_allclose(read_take(path).xyz, xyz, atol=1e-6)
        return
    with pytest.raises(MocapError) as err:
        read_take(path)
    msg = str(err.value)
    assert str(path) in msg and "take 'take'" in msg and f"field '{field}'" in msg and words in msg, msg


def test_two_motive_markers_of_one_name_are_refused_not_merged(tmp_path):
    """Before, the second one's columns made 6 'found' axes; now the message says what happened."""
    path = tmp_path / "take.csv"
    motive_csv(path, ["A", "A"], np.arange(60, dtype=float).reshape(10, 2, 3), 100.0)
    with pytest.raises(
        MocapError, match=r"field 'A Position'.*2 markers are named 'A' \(columns 3, 4, 5, 6, 7, 8\)"
    ):
        read_take(path)


def test_two_motive_rigid_bodies_of_one_name_are_unusable_not_the_last_one(tmp_path):
    """Before, the second body's columns silently replaced the first's."""
    path = tmp_path / "take.csv"
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (10, 1))
    motive_csv(path, [], np.zeros((10, 0, 3)), 100.0, body=("quad", quat, np.zeros((10, 3))))
    lines = path.read_text().splitlines()
    rows = [r.split(",") for r in lines[2:]]
    body = [j for j in range(len(rows[0])) if rows[0][j] == "Rigid Body"]
    path.write_text("\n".join(lines[:2] + [",".join(r + [r[j] for j in body]) for r in rows]) + "\n")
    tk = read_take(path)
    assert "quad" not in tk.bodies
    assert "two rigid bodies are named 'quad'" in tk.unusable["quad"], tk.unusable


@pytest.mark.parametrize(
    ("edit", "field", "words"),
    [
        (lambda t: t, None, None),
        (
            lambda t: t.replace("MARKER_NAMES\tA\tB", "MARKER_NAMES\tA\t\tB"),
            "MARKER_NAMES",
            "marker 2 has no name",
        ),
        (lambda t: t.replace("\tB X\tB Y\tB Z", "\tB X\tB Y"), "line 12, column 8", "expected 'B Z'"),
        (
            lambda t: t.replace("MARKER_NAMES\tA\tB", "MARKER_NAMES\tB\tA"),
            "line 12, column 3",
            "expected 'B X'",
        ),
    ],
)
def test_qualisys_columns_that_do_not_match_the_marker_names(tmp_path, edit, field, words):
    """An empty name or a column header at odds with MARKER_NAMES would shift every marker's
    columns silently."""
    xyz = np.arange(1, 10 * 2 * 3 + 1, dtype=float).reshape(10, 2, 3) * 1e-3
    path = tmp_path / "take.tsv"
    qualisys_tsv(path, ["A", "B"], xyz, 100.0)
    path.write_text(edit(path.read_text()))
    if field is None:
        np.testing.assert_allclose(read_take(path).xyz, xyz, atol=1e-6)
        return
    with pytest.raises(MocapError) as err:
        read_take(path)
    msg = str(err.value)
    assert str(path) in msg and f"field '{field}'" in msg and words in msg, msg


HOSTILE = [
    None,
    "",
    "x",
    "\0",
    -1,
    0,
    2.5,
    10**400,
    -(10**400),
    math.nan,
    math.inf,
    True,
    [],
    {},
    [1, "a"],
    {"a": 1},
]
RICH_MARKERS = {
    "schema": "slopelander.markers/1",
    "units": "mm",
    "body": {
        "markers": {"A": [120, -45, 30], "B": [110, 60, 25], "C": [-125, 10, 35]},
        "rigid_tolerance": 5,
    },
    "roof": {"markers": ["R1", "R2", "R3"], "marker_height": 7},
    "feet": {"markers": ["F1", "F2"], "marker_height": 10},
    "up_axis": "+Z",
    "latency_s": 0.01,
    "rates": {"window_s": 0.03, "polyorder": 2},
    "planarity": {"lateral": 20, "yaw_deg": 5, "roll_deg": 5},
    "keep": {"before_s": 0.1, "after_s": 0.5},
    "conditions": {"tau_up": 1.1, "outcome": "ideal"},
    "takes": {"drop01.c3d": {"tau_down": 1.7}},
}
RIGID_MARKERS = {
    "schema": "slopelander.markers/1",
    "units": "m",
    "body": {"rigid_body": "quad", "centre_of_mass": [0, 0, -0.02], "forward": "+X", "up": "+Y"},
    "roof": {"plane": {"point": [0, 0, 0], "normal": [0, 1, 0.3]}},
    "takes": "takes.csv",
}


def _leaf_paths(node, prefix=()):
    """Every path to a value in a YAML tree, the root's included."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaf_paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _leaf_paths(v, (*prefix, i))


def _replaced(doc, path, value):
    doc = copy.deepcopy(doc)
    if not path:
        return value
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    parent[path[-1]] = value
    return doc


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_wrong_typed_value_anywhere_in_a_markers_file_is_refused_naming_the_file(data, tmp_path):
    """Any value of the markers file replaced by one of another type (or a hostile one): the
    file loads, or load_markerset raises its own MocapError naming the file, never a bare error."""
    base = data.draw(
        st.sampled_from([yaml.safe_load((EXAMPLE / "markers.yaml").read_text()), RICH_MARKERS, RIGID_MARKERS])
    )
    path = data.draw(st.sampled_from(list(_leaf_paths(base))))
    value = data.draw(
        st.one_of(st.sampled_from(HOSTILE), st.lists(st.integers(), max_size=4), st.text(max_size=8))
    )
    (tmp_path / "takes.csv").write_text((EXAMPLE / "takes.csv").read_text())
    markers = tmp_path / "markers.yaml"
    markers.write_text(yaml.safe_dump(_replaced(base, path, value), allow_unicode=True))
    try:
        load_markerset(markers)
    except MocapError as exc:
        assert str(markers) in str(exc) or str(tmp_path) in str(exc), exc
