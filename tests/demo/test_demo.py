"""The main job, as a user runs it: `slopelander demo` flies a whole simulated landing."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from pymavlink import mavutil

from slopelander.controller.config import load_config
from slopelander.controller.landing import (
    cut_dynamics,
    expected_impact_speed,
    landing_cut_height,
    leg_geometry,
)
from slopelander.controller.session import read_transitions as transitions
from slopelander_sitl.vehicle.scenario import Scenario
from slopelander_sitl.vehicle.script_io import RANGEFINDER_PERIOD_MS

#: its tests share one demo run (demo): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("demo/demo")

REPO = Path(__file__).resolve().parents[2]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), str(REPO), env.get("PYTHONPATH", "")])
    return env


CFG = load_config()
#: the window of the steady descent read: it ends WINDOW_GAP_S before the companion's CUT, since
#: the feet may meet the roof before the cut is heard (the script cuts on the second 20 Hz range
#: sample below the cut height and the cut latency is 0.075 s), and lasts twice that gap
WINDOW_GAP_S = 0.3
#: RAW_IMU's resolution (1 milli-g) over the <= 20 ms from the last 50 Hz velocity to the contact,
#: which first_contact_speed carries on with the accelerometer (demo.py)
IMU_CARRY_MPS = 9.80665e-3 * 0.02
#: the script cuts on the second distinct 20 Hz range sample at or below the cut height, so the
#: motors stop one to two sample periods after the range crosses it (docs/onboard-script.md, "The
#: cut"), plus a script cycle (<= 10 ms). The plan's impact speed uses the mean, 75 ms. Each
#: sample carries the simulated rangefinder's noise: a sample up to NOISE_SIGMAS sigma low reads
#: the cut height that much early, one as high reads it that much late. On the 35 deg roof the
#: uphill foot touches 2 cm below the cut height, 42 ms after the crossing at 0.5 m/s: a cut in
#: the early part of this band stops the motors before the contact (seen in about 1 run in 7).
NOISE_SIGMAS = 3.0
SCRIPT_CYCLE_S = 0.01


def _descent_flown(out: Path) -> tuple[float, float]:
    """The descent speed flown (m/s, down) at the contact and how far the speed at contact may lie
    from what it predicts. At 0.5 m/s and 0.075 s cut latency the feet touch before the cut acts,
    so the impact speed is the speed the autopilot was tracking, not the commanded rate (it still
    drifts, a few mm/s over the last second). Its LOCAL_POSITION_NED vz over the 0.6 s window
    ending WINDOW_GAP_S before the CUT, fitted with a line and carried on to the CUT; the contact
    lies somewhere in the gap, so the tolerance is the drift over the gap, plus the reports'
    largest scatter about the line (either side), plus the IMU carry."""
    t_cut = next(ln["t"] for ln in transitions(out / "transitions.jsonl") if ln["to"] == "CUT")
    log = mavutil.mavlink_connection(str(out / "flight.tlog"))
    pts = []
    while (msg := log.recv_match(type="LOCAL_POSITION_NED")) is not None:
        t = msg.time_boot_ms / 1000.0
        if t_cut - 3 * WINDOW_GAP_S <= t <= t_cut - WINDOW_GAP_S:
            pts.append((t - t_cut, msg.vz))
    assert len(pts) >= 20, pts  # 0.6 s at 50 Hz: 30 reports
    n = len(pts)
    mt, mv = sum(t for t, _ in pts) / n, sum(v for _, v in pts) / n
    slope = sum((t - mt) * (v - mv) for t, v in pts) / sum((t - mt) ** 2 for t, _ in pts)
    scatter = max(abs(v - (mv + slope * (t - mt))) for t, v in pts)
    at_cut = mv - slope * mt
    return at_cut, abs(slope) * WINDOW_GAP_S + 2 * scatter + IMU_CARRY_MPS


def _cut_latency_band(descent_mps: float) -> tuple[float, float]:
    """The earliest and the latest the motors can stop after the range crosses the cut height (s)."""
    period = RANGEFINDER_PERIOD_MS / 1000.0
    noise_s = NOISE_SIGMAS * Scenario().range_noise / descent_mps
    return max(0.0, period - noise_s), 2 * period + SCRIPT_CYCLE_S + noise_s


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
    seq = [ln["to"] for ln in transitions(out / "transitions.jsonl")]
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
    # the speed at the first foot contact against what the descent speed actually flown predicts
    flown, tolerance = _descent_flown(out)
    early, late = _cut_latency_band(flown)
    slowest, fastest = (
        expected_impact_speed(
            flown,
            result["cut_height_m"],  # the landing's, raised on this 35 deg roof
            result["slope_deg"],
            leg_geometry(),
            result["uphill_angle_deg"],
            cut_dynamics(latency),
        )
        for latency in (late, early)
    )
    assert slowest - tolerance <= result["impact_mps"] <= fastest + tolerance, (
        result["impact_mps"],
        (slowest, fastest),
        flown,
        tolerance,
    )
    assert result["slide_m"] < 1.0  # it stayed on the roof
    assert result["cut_height_m"] == landing_cut_height(
        CFG["reflex.cut_height_m"],
        CFG["descent.rate_mps"],
        result["slope_deg"],
        leg_geometry(),
        result["uphill_angle_deg"],
    )


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
