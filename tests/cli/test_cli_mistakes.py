"""Ordinary mistakes on the command line: one clear line, before any work is done."""

from __future__ import annotations

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
    assert main(["simulate", "--rvt", "--without", "rotors"]) == 1
    assert "reverse thrust needs the rotors" in capsys.readouterr().err


def test_leg_angle_outside_the_travel_is_refused_before_opening_the_port(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["legs", "angle", "--port", "/nonexistent/port", "--uphill", "50"])
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
