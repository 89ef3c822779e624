"""The main job, as a user runs it: `slopelander demo` flies a whole simulated landing."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), str(REPO), env.get("PYTHONPATH", "")])
    return env


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess, Path]:
    out = tmp_path_factory.mktemp("demo") / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "demo", "--out", str(out), "--time-scale", "3"],
        capture_output=True,
        text=True,
        timeout=400,
        env=_env(),
        cwd=REPO,
    )
    return proc, out


def test_the_demo_lands_on_the_roof_takes_off_and_resets_the_legs(demo) -> None:
    proc, out = demo
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "outcome: LANDED_AND_RESET" in proc.stdout
    seq = [json.loads(line)["to"] for line in (out / "transitions.jsonl").read_text().splitlines()]
    assert seq == [
        "PRESET",
        "LEGS_WAIT",
        "CHECKS",
        "DESCEND",
        "ARMED",
        "CUT",
        "REVERSE",
        "SETTLED",
        "LANDED",
        "TAKEOFF",
        "RESET",
        "READY",
    ]
    result = json.loads((out / "result.json").read_text())
    assert result["outcome"] == "LANDED_AND_RESET"
    # the speed at the first foot contact, as predicted from descent rate, cut height and legs
    # (0.567 m/s); flown: 0.52-0.57 m/s, and once 0.45 m/s in a full test run, where the
    # lock-step timing of the cut varies with load (2026-11-23)
    assert result["impact_mps"] == pytest.approx(result["expected_impact_mps"], rel=0.25)
    assert result["slide_m"] < 1.0  # it stayed on the roof


def test_the_demo_sets_the_tables_uphill_angle_on_the_board(demo) -> None:
    proc, out = demo
    result = json.loads((out / "result.json").read_text())
    assert result["uphill_angle_deg"] is not None and result["uphill_angle_deg"] < 37.0
    # the simulated board has the angle actuator: its uphill legs rest at the table's angle, not
    # at their 37.5 deg stop, when the motors are cut
    assert abs(result["uphill_angle_measured_deg"] - result["uphill_angle_deg"]) <= 0.5
    assert f"uphill legs: preset {result['uphill_angle_deg']:.1f} deg" in proc.stdout


def test_the_demo_writes_a_telemetry_log_mavlogdump_reads_and_a_picture(demo) -> None:
    proc, out = demo
    assert proc.returncode == 0, proc.stderr
    dump = subprocess.run(
        [
            sys.executable,
            "-m",
            "pymavlink.tools.mavlogdump",
            "--types",
            "STATUSTEXT",
            str(out / "flight.tlog"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert dump.returncode == 0, dump.stderr
    assert "Arming motors" in dump.stdout
    png = (out / "flight.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000


def test_a_demo_into_an_unwritable_place_stops_before_starting_anything(tmp_path: Path) -> None:
    target = tmp_path / "missing" / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "demo", "--out", str(target)],
        capture_output=True,
        text=True,
        timeout=120,
        env=_env(),
        cwd=REPO,
    )
    assert proc.returncode == 1
    assert "does not exist" in proc.stderr and "Traceback" not in proc.stderr
