"""Ordinary mistakes on the command line: one clear line, before any work is done."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from slopelander import __version__
from slopelander.cli import main


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"slopelander {__version__}"


def test_help_shows_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "surface slope, deg (default: 0.0)" in out
    assert "vertical impact speed, m/s (default: 2.0)" in out


@pytest.mark.parametrize("flag", ["--plot", "--csv"])
def test_output_into_a_missing_folder_is_refused_before_simulating(
    flag: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "missing" / "out.file"
    assert main(["simulate", flag, str(target)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "does not exist" in err and str(target.parent) in err
    assert not target.parent.exists()


def test_output_onto_a_folder_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--csv", str(tmp_path)]) == 1
    assert "is a folder" in capsys.readouterr().err


def test_reverse_thrust_without_rotors_is_a_contradiction(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--reverse", "--without", "rotors"]) == 1
    assert "reverse thrust needs the rotors" in capsys.readouterr().err


def test_leg_angle_outside_the_travel_is_refused_before_opening_the_port(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["legs", "angle", "--legs-port", "/nonexistent/port", "--angle-up", "50"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "50 deg is outside the legs' travel 0..37.5 deg" in err
    assert "Traceback" not in err


def test_lookup_prints_the_tables_preset(capsys: pytest.CaptureFixture[str]) -> None:
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable

    assert main(["lookup", "--slope", "35", "--speed", "1.5"]) == 0
    out = capsys.readouterr().out
    p = LookupTable.load(DEFAULT_TABLE).lookup(35, 1.5)
    assert f"uphill {p.tau_up:.2f} N*m, downhill {p.tau_down:.2f} N*m" in out
    assert f"leg angle uphill {p.angle_up_deg:.1f} deg" in out and p.outcome in out


def test_lookup_outside_the_table_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["lookup", "--slope", "75", "--speed", "1.5"]) == 1
    err = capsys.readouterr().err
    assert "outside the table's range" in err and err.count("\n") == 1


# -- where map and table write: one rule, checked before any work ----------------------------
TINY = ["--slope-step", "30", "--speed-step", "1.0", "--speed-min", "1.0", "--quiet"]


@pytest.mark.parametrize("command", [["map", "symmetric"], ["table"]])
def test_map_and_table_refuse_a_missing_parent_folder(
    command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "missing" / "out"
    assert main([*command, "--out", str(target), *TINY]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "does not exist (create it first)" in err
    assert str(target.parent) in err and not target.parent.exists()


def test_map_into_an_existing_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "taken"
    target.write_text("mine\n")
    assert main(["map", "symmetric", "--out", str(target), *TINY]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a file; give a folder" in err
    assert target.read_text() == "mine\n"


@pytest.mark.parametrize("command", [["map", "symmetric"], ["table"], ["simulate", "--csv"]])
def test_an_output_under_a_file_is_refused(
    command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain = tmp_path / "plain.txt"
    plain.write_text("x\n")
    flag = [] if command[0] == "simulate" else ["--out"]
    assert main([*command, *flag, str(plain / "out"), *(TINY if command[0] != "simulate" else [])]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{plain} is a file, not a folder" in err


def test_table_onto_a_folder_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["table", "--out", str(tmp_path), *TINY]) == 1
    assert "is a folder; give a file name" in capsys.readouterr().err


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
@pytest.mark.parametrize("command", [["map", "symmetric"], ["table"]])
def test_map_and_table_refuse_an_unwritable_place(
    command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        t0 = time.perf_counter()
        assert main([*command, "--out", str(locked / "out.yaml"), *TINY]) == 1
        assert time.perf_counter() - t0 < 2.0  # refused before any landing is simulated
    finally:
        locked.chmod(0o700)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not writable" in err
    assert list(locked.iterdir()) == []


def test_map_creates_its_own_folder_when_the_parent_exists(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "new"
    assert main(["map", "symmetric", "--out", str(out), *TINY]) == 0
    assert (out / "symmetric.png").is_file()


def _interrupt_a_map(kind: str, out: Path, ready: Path) -> subprocess.CompletedProcess[str]:
    """A real ``slopelander map`` process, sent SIGINT once ``ready`` exists and it is working."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from slopelander.cli import main; sys.exit(main())",
            "map",
            kind,
            "--out",
            str(out),
            "--slope-step",
            "2",
            "--speed-step",
            "0.1",
            "--draws",
            "50",
            "--quiet",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        # Ctrl-C as at a terminal: a suite started in the background (``nohup ... &``) passes
        # its ignored SIGINT on to its children, and Python then never raises KeyboardInterrupt
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 60
    while not ready.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.1)
    time.sleep(3.0)  # well inside the sweep (which takes minutes at this grid)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)


@pytest.mark.parametrize(
    ("kind", "ready", "written"),
    [
        ("robustness", "", False),  # writes its files only at the end
        ("uncertainty", "params_set3.yaml", True),
    ],  # writes its parameter sets first
)
def test_ctrl_c_during_a_map_stops_cleanly_and_says_what_was_written(
    kind: str, ready: str, written: bool, tmp_path: Path
) -> None:
    out = tmp_path / "map"
    done = _interrupt_a_map(kind, out, out / ready)
    assert done.returncode == 130, done.stderr
    assert "Traceback" not in done.stderr
    last = done.stderr.strip().splitlines()[-1]
    on_disk = sorted(p for p in out.rglob("*") if p.is_file())
    assert bool(on_disk) is written
    if written:
        assert last.startswith("slopelander map: interrupted; partial results written: ")
        assert all(str(p) in last for p in on_disk)
    else:
        assert last == "slopelander map: interrupted; nothing written"


def _subcommand_helps() -> dict[str, str]:
    import argparse

    from slopelander.cli import build_parser

    helps: dict[str, str] = {}

    def walk(parser: argparse.ArgumentParser, name: str) -> None:
        helps[name] = parser.format_help()
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub, p in action.choices.items():
                    walk(p, f"{name} {sub}".strip())

    walk(build_parser(), "")
    return helps


def test_help_shows_each_default_once_and_no_empty_default() -> None:
    helps = _subcommand_helps()
    assert {"simulate", "map", "table", "params", "legs set"} <= set(helps)
    for name, text in helps.items():
        flat = " ".join(text.split())
        assert "(default: None)" not in flat, name
        assert "(default: False)" not in flat, name
        for chunk in flat.split(" --")[1:]:  # one option's help each
            assert chunk.lower().count("default") - chunk.count("defaults") <= 1, (name, chunk)
