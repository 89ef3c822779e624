"""Outputs that cannot be written are refused in one line before any work, for root too (which
passes every permission check, yet cannot create a file in /proc); ``map`` prints numbers a
person reads."""

from __future__ import annotations

import ast
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from slopelander.cli import main

TINY = ["--slope-step", "30", "--speed-step", "1.0", "--speed-min", "1.0", "--quiet"]

# Run a command in a fresh process and report which of the modules that do the work it imported:
# a refusal "before the work" imports none of them.
WORK = (
    "numba",
    "scipy",
    "matplotlib",
    "slopelander.model",
    "slopelander.envelope.reports",
    "slopelander_sitl.rig",
    "slopelander_sitl.vehicle",
)
PROBE = (
    "import sys; from slopelander.cli import main; rc = main(sys.argv[1:]); "
    f"print(sorted(m for m in {WORK!r} if m in sys.modules)); sys.exit(rc)"
)


def run_fresh(argv: list[str]) -> tuple[int, str, list[str]]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    done = subprocess.run(
        [sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, env=env, timeout=600
    )
    lines = done.stdout.strip().splitlines()
    return done.returncode, done.stderr, (ast.literal_eval(lines[-1]) if lines else ["(nothing printed)"])


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--plot", "/proc/x.png"],
        ["simulate", "--csv", "/proc/x.csv"],
        ["map", "rvt", "--out", "/proc/maps", *TINY],
        ["table", "--out", "/proc/t.yaml", *TINY],
        ["params", "--out", "/proc/p.yaml"],
        ["synth", "--out", "/proc/drops", "--drops", "1"],
        ["demo", "--out", "/proc/demo"],
    ],
    ids=lambda a: " ".join(a[:3]),
)
def test_an_output_in_proc_is_refused_before_the_work(argv: list[str]) -> None:
    code, err, imported = run_fresh(argv)
    assert code == 1, err
    assert err.count("\n") == 1, err
    assert "folder /proc is not writable" in err
    assert imported == []  # refused before the model or the maps were even imported


def test_an_existing_output_folder_that_takes_no_files_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["map", "rvt", "--out", "/proc/self", *TINY]) == 1
    assert "folder /proc/self is not writable" in capsys.readouterr().err


def test_the_write_check_leaves_nothing_behind(tmp_path: Path) -> None:
    from slopelander.outputs import check_output, check_output_dir

    (tmp_path / "kept.csv").write_text("mine\n")
    check_output(tmp_path / "kept.csv", "--csv")
    check_output(tmp_path / "new.csv", "--csv")
    check_output_dir(tmp_path / "new", "--out")
    check_output_dir(tmp_path, "--out")
    assert [p.name for p in tmp_path.iterdir()] == ["kept.csv"]
    assert (tmp_path / "kept.csv").read_text() == "mine\n"


def test_map_prints_rounded_numbers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # six landed cells of 0.3 deg x 0.5 m/s: an area float arithmetic makes 0.8999999999999999
    grid = ["--slope-step", "0.3", "--slope-max", "0.3", "--speed-step", "0.5", "--speed-min", "1.0"]
    grid += ["--speed-max", "2.0"]
    assert main(["map", "symmetric", "--out", str(tmp_path), *grid, "--quiet"]) == 0
    out = capsys.readouterr().out
    printed = json.loads(out)
    numbers = re.findall(r"-?\d+\.\d+(?:e-?\d+)?", out)
    assert numbers and all(len(n.lstrip("-").replace(".", "").lstrip("0")) <= 7 for n in numbers), numbers
    full = json.loads((tmp_path / "symmetric_summary.json").read_text())
    assert full["area_landed_deg_mps"] == 6 * 0.15 != 0.9  # the unrounded value, as the file keeps it
    assert printed["area_landed_deg_mps"] == 0.9
    for key, value in printed.items():
        if isinstance(value, float) and value == value and key != "seconds":
            assert value == pytest.approx(full[key], rel=1e-6)


def test_demo_speed_is_now_time_scale(capsys: pytest.CaptureFixture[str]) -> None:
    """One word, one meaning: --speed is the impact speed (simulate, lookup); the demo's rate of
    simulated time is --time-scale, and the old spelling says so instead of running."""
    with pytest.raises(SystemExit) as exc:
        main(["demo", "--speed", "3"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "the simulation rate is now --time-scale 3" in err
    from slopelander.cli import build_parser

    demo = build_parser()._subparsers._group_actions[0].choices["demo"]
    assert demo.parse_args(["--time-scale", "3"]).time_scale == 3.0
    assert "--speed" not in demo.format_help()
