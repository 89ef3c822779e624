"""``slopelander demo --autopilot ardupilot``: the whole demo (take-off from the pad, over the
roof, landing, disarm, take-off, legs loosened) on real ArduCopter SITL, with the same printout,
tlog, transitions and picture as on the simulated vehicle, and ArduCopter's own DataFlash log
(``flight.bin``), which ``compare`` reads. Skipped, saying why, without ``SLOPELANDER_ARDUCOPTER``;
about 1.5 minutes of wall time."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from slopelander.controller.script_contract import SCRIPT_CONTRACT
from slopelander.controller.session import read_transitions as transitions
from slopelander.ident.flightlog.compare import compare_log
from slopelander.model import Model
from slopelander_sitl.ardupilot import arducopter_binary
from slopelander_sitl.ardupilot.launch import ArduCopterMissingError
from tests.ident.test_flightlog import true_contact

# one ArduCopter at a time; a long flight (tests/conftest.py)
pytestmark = [pytest.mark.xdist_group("arducopter"), pytest.mark.timeout(1200)]


def landed_legs(printed: str) -> tuple[float, float]:
    """The torques the demo says it landed with ("demo: 35 deg roof, legs 1.10/1.10 N*m ...")."""
    m = re.search(r"legs (\d+\.\d+)/(\d+\.\d+) N\*m", printed)
    assert m, printed[:400]
    return float(m.group(1)), float(m.group(2))


def reported_uphill(printed: str) -> float:
    """The uphill legs' angle the demo says the board reported ("board reported 25.7 deg")."""
    m = re.search(r"board reported (\d+\.\d+) deg", printed)
    assert m, printed[:400]
    return float(m.group(1))


def test_the_demo_flies_on_real_arducopter_and_ends_disarmed_then_reset(tmp_path: Path) -> None:
    try:
        arducopter_binary()
    except ArduCopterMissingError as exc:
        if os.environ.get("SLOPELANDER_ARDUCOPTER"):
            pytest.fail(str(exc))
        pytest.skip(str(exc))
    out = tmp_path / "demo"
    r = subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "demo", "--autopilot", "ardupilot", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "firmware 4." in r.stdout and f"on-board script v{SCRIPT_CONTRACT}" in r.stdout, r.stdout[:800]
    assert "outcome: LANDED_AND_RESET" in r.stdout
    lines = transitions(out / "transitions.jsonl")
    states = [ln["to"] for ln in lines]
    assert states[-4:] == ["LANDED", "TAKEOFF", "RESET", "READY"], states
    landed = next(ln for ln in lines if ln["to"] == "LANDED")
    assert "seen in the HEARTBEAT" in landed["reason"]  # a disarm made, not a disarm sent
    assert (out / "flight.tlog").stat().st_size > 10_000
    assert (out / "flight.png").stat().st_size > 10_000
    # ArduCopter's own DataFlash log is kept, and compare reads the landing from it and from the
    # tlog: the same first contact, within a sample of SITL's own state logged beside it
    assert f"DataFlash log: {out / 'flight.bin'}" in r.stdout
    model = Model.default()
    [from_bin] = compare_log(model, out / "flight.bin")
    [from_tlog] = compare_log(model, out / "flight.tlog")
    lo, hi = true_contact(out / "flight.bin", near=from_bin.contact)
    assert abs(from_bin.contact - 0.5 * (lo + hi)) <= 0.003, (from_bin.contact, lo, hi)  # 400 Hz IMU
    assert abs(from_tlog.contact - 0.5 * (lo + hi)) <= 0.005, (from_tlog.contact, lo, hi)  # 200 Hz
    for r_ in (from_bin, from_tlog):
        c = r_.cond.conditions
        assert abs(c.slope_deg - 35.0) <= max(1.5, 2 * r_.cond.slope.sigma_deg), r_.cond.slope.describe()
        assert (c.tau_up, c.tau_down) == landed_legs(r.stdout)
        # the legs as the board reported them: from the companion's message, which ArduPilot logs
        # (the companion's tlog holds what it heard, not what it said: transitions.jsonl beside it)
        source = r_.cond.sources["leg angles"]
        where = "the companion's message" if r_ is from_bin else "transitions.jsonl beside the log"
        assert source.startswith(f"as the leg board reported them, {where}"), source
        assert abs(c.angle_up_deg - reported_uphill(r.stdout)) <= 0.3, (c.angle_up_deg, r.stdout[:400])


def test_the_demo_without_a_binary_says_how_to_get_one(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "SLOPELANDER_ARDUCOPTER"}
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "slopelander.cli",
            "demo",
            "--autopilot",
            "ardupilot",
            "--out",
            str(tmp_path / "d"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert r.returncode != 0
    assert "SLOPELANDER_ARDUCOPTER" in r.stderr and "./waf" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "d").exists()  # nothing started, nothing written
