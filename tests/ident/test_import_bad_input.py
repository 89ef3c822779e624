"""slopelander import on bad input: one line naming the file, the take and the field, before
any take is solved, and nothing in (or beside) the output folder. A real process each."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from slopelander.ident.mocap.formats import read_take, write_c3d
from tests.ident.mocap_files import motive_csv, vicon_csv

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
