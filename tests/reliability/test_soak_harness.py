"""The soak's own parts that decide what it flies and what it reads back (benchmarks/soak.py): its
append-only log and ``--resume``, and the copy of the on-board script whose injected error it
flies on ArduCopter, run here in real Lua on the script bench."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.soak import SCRIPT_HOOK, hooked_script, read_log
from slopelander.controller.script_contract import ScriptState
from tests.firmware.script_bench import Bench

REPO = Path(__file__).resolve().parents[2]


def soak(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "soak.py"), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_log_gives_its_settings_and_landings_and_leaves_out_a_last_line_cut_short(tmp_path: Path) -> None:
    log = tmp_path / "soak.jsonl"
    log.write_text(
        json.dumps({"run": {"seed": 3}})
        + "\n"
        + json.dumps({"i": 0, "end": "READY"})
        + "\n"
        + json.dumps({"i": 1, "end": "ABORTED"})
        + '\n{"i": 2, "en'  # the run was killed while writing it
    )
    head, rows = read_log(log)
    assert head == {"seed": 3}
    assert [r["i"] for r in rows] == [0, 1]


def test_a_bad_line_inside_the_log_is_named_by_its_number(tmp_path: Path) -> None:
    log = tmp_path / "soak.jsonl"
    log.write_text('{"i": 0}\nnot json\n{"i": 1}\n')
    with pytest.raises(ValueError, match="line 2"):
        read_log(log)


def test_a_run_keeps_an_existing_log_and_a_resume_keeps_the_logs_settings(tmp_path: Path) -> None:
    log = tmp_path / "soak.jsonl"
    log.write_text(json.dumps({"run": {"seed": 3}}) + "\n")
    fresh = soak("--log", str(log), "--landings", "1")
    assert fresh.returncode == 2 and "exists: --resume to go on with it" in fresh.stderr, fresh.stderr
    other = soak("--log", str(log), "--resume", "--seed", "4", "--landings", "1")
    assert other.returncode == 2 and "--seed 3 (now 4)" in other.stderr, other.stderr
    missing = soak("--log", str(tmp_path / "none.jsonl"), "--resume")
    assert missing.returncode == 2 and "--resume needs --log" in missing.stderr, missing.stderr
    assert log.read_text() == json.dumps({"run": {"seed": 3}}) + "\n"  # untouched


def test_three_landings_of_the_soak_fly_to_safe_ends_on_the_simulated_vehicle(tmp_path: Path) -> None:
    """The soak end to end, so a change elsewhere cannot leave it unable to fly: seed 1's first
    landings are a pilot's LOITER, a link cut for good in REVERSE and a 0.5 s cut, each followed
    by the take-off. Two breaks went unseen before this test: the loop waited on a leg-board
    method that was gone (every landing a rig error), and a take-off refused for the pilot's
    centred throttle went LANDED -> TAKEOFF for ever (both landings a hang)."""
    log = tmp_path / "soak.jsonl"
    run = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "soak.py"),
            "--landings",
            "3",
            "--seed",
            "1",
            "--log",
            str(log),
            "--results",
            "-",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    _, rows = read_log(log)
    ends = [(r["fault"], r["end"], r.get("reason"), r["unsafe"]) for r in rows]
    assert len(rows) == 3, ends
    assert all(not unsafe and end in ("READY", "ABORTED", "LANDED") for _, end, _, unsafe in ends), ends
    assert sum(end == "READY" for _, end, _, _ in ends) >= 2, ends  # landed and took off again
    assert "hangs: 0; unsafe ends: 0" in run.stdout, run.stdout[-1500:]


def test_the_script_copy_raises_only_once_scr_user1_is_set_to_1(tmp_path: Path) -> None:
    """Inert until the soak sets the parameter (ArduCopter's SCR_USER1 is 0 at boot); then the
    update raises and the script's pcall leaves FAULT, the error reported."""
    path = hooked_script(tmp_path)
    assert path.read_text().count(SCRIPT_HOOK) == 1
    b = Bench(path)
    b.io.params["SCR_USER1"] = 0.0
    b.run(100)
    assert b.host.running and b.io.state() == ScriptState.IDLE
    b.io.params["SCR_USER1"] = 1.0
    b.run(50)
    assert b.host.running, b.host.error
    assert b.io.state() == ScriptState.FAULT
    assert any(t.endswith(": injected fault") for t in b.io.sl_texts()), b.io.sl_texts()
