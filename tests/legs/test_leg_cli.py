"""``slopelander legs ...`` against the simulated board."""

from __future__ import annotations

import pytest

from slopelander import cli


@pytest.fixture
def run(monkeypatch, capsys):
    # The worktree may not have every part's subcommands yet; the legs part is enough here.
    monkeypatch.setattr(cli, "SUBCOMMAND_MODULES", {"slopelander.commands.legs": (("legs",), False)})

    def run_cli(*argv: str) -> tuple[int, str, str]:
        code = cli.main(list(argv))
        out = capsys.readouterr()
        return code, out.out, out.err

    return run_cli


def test_status_set_loosen(board, run):
    port = str(board.link)
    code, out, _ = run("legs", "status", "--legs-port", port)
    assert code == 0 and out.count("LOOSE") == 4 and "ASSUMED" in out
    code, out, _ = run(
        "legs",
        "set",
        "--legs-port",
        port,
        "--tau-up",
        "1.7",
        "--tau-down",
        "2.3",
        "--timeout",
        str(board.wall(20)),
    )
    assert code == 0 and sum(line.startswith("leg ") for line in out.splitlines()) == 4
    assert "ASSUMED calibration" in out
    with board.ctl() as ctl:
        torques = ctl.friction_torques()
    assert torques == pytest.approx([1.7, 1.7, 2.3, 2.3], abs=0.15)
    code, out, _ = run("legs", "loosen", "--legs-port", port, "--timeout", str(board.wall(20)))
    assert code == 0 and out.count("37.50 °") == 4


def test_errors_are_one_clear_line(board, run):
    code, _, err = run("legs", "set", "--legs-port", str(board.link), "--leg", "1=9")
    assert code == 1 and "Traceback" not in err
    assert "legs: error: leg 1: 9.0 N·m is outside the calibrated range" in err
    code, _, err = run("legs", "status", "--legs-port", "/nonexistent/tty", "--timeout", "1")
    assert code == 1 and "cannot open leg board port /nonexistent/tty" in err


def test_set_from_the_lookup_table(board, run):
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable

    p = LookupTable.load(DEFAULT_TABLE).lookup(35, 1.5)
    code, out, err = run(
        "legs",
        "set",
        "--legs-port",
        str(board.link),
        "--table",
        "--slope",
        "35",
        "--speed",
        "1.5",
        "--timeout",
        str(board.wall(20)),
    )
    assert code == 0, err
    assert f"uphill {p.tau_up:.2f} N·m, downhill {p.tau_down:.2f} N·m" in out
    with board.ctl() as ctl:
        torques = ctl.friction_torques()
    assert torques[0] == pytest.approx(p.tau_up, abs=0.15)
    assert torques[3] == pytest.approx(p.tau_down, abs=0.15)


def test_set_from_the_table_needs_slope_and_speed(run):
    code, _, err = run("legs", "set", "--legs-port", "/nonexistent", "--table", "--slope", "35")
    assert code == 1 and "--table needs --slope and --speed" in err
