"""``slopelander map`` and ``slopelander table`` write readable files from a tiny grid."""

from __future__ import annotations

import json

import pytest

from slopelander.cli import build_parser, main
from slopelander.controller.table import LookupTable

GRID = ["--slope-step", "30", "--speed-step", "1.0", "--speed-min", "1.0", "--quiet"]


@pytest.mark.parametrize("kind", ["symmetric", "asymmetric", "rigid", "uncertainty", "robustness"])
def test_map_writes_png_data_and_a_summary(kind, tmp_path, capsys):
    assert main(["map", kind, "--out", str(tmp_path), *GRID, "--draws", "2"]) == 0
    printed = json.loads(capsys.readouterr().out)
    summary = json.loads((tmp_path / f"{kind}_summary.json").read_text())
    assert printed["kind"] == summary["kind"] == kind
    pngs = list(tmp_path.glob("*.png"))
    assert pngs and all(p.stat().st_size > 10_000 for p in pngs)
    assert list(tmp_path.glob("*.csv")) and list(tmp_path.glob("*.npz"))
    if kind == "rigid":
        assert "area_ratio_fsa_rvt_vs_rigid" in summary
    if kind == "robustness":
        assert summary["nominal_cells"] > 0  # level landings succeed on this grid (0 deg, 1-3 m/s)
        assert 0.0 <= summary["overall_success_rate"] <= 1.0
    if kind == "uncertainty":
        assert len(list(tmp_path.glob("params_set*.yaml"))) == 3


def test_table_command_writes_a_table_the_controller_loads(tmp_path, capsys):
    out = tmp_path / "table.yaml"
    assert main(["table", "--out", str(out), *GRID]) == 0
    assert "wrote" in capsys.readouterr().out
    t = LookupTable.load(out)
    assert t.slope_range == (0.0, 60.0) and t.speed_range == (1.0, 3.0)


def test_a_bad_grid_is_an_error_message_not_a_traceback(tmp_path, capsys):
    assert main(["map", "symmetric", "--out", str(tmp_path), "--slope-step", "0"]) == 1
    assert "step must be positive" in capsys.readouterr().err


def test_the_main_command_lists_map_and_table(capsys):
    from slopelander.commands import map as map_command
    from slopelander.commands import table as table_command

    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    lines = {line.split()[0]: line for line in out.splitlines() if line.startswith("    ") and line.split()}
    assert {"map", "table", "demo", "land", "simulate", "legs", "lookup", "params"} <= set(lines)
    # listed as working commands, not as stubs asking for an extra
    assert not [name for name, line in lines.items() if "needs:" in line]
    assert "landing maps" in lines["map"] and "lookup table" in lines["table"]
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert sub.choices["map"].get_default("handler") is map_command.run
    assert sub.choices["table"].get_default("handler") is table_command.run


def test_a_table_with_the_thrust_ended_records_it_and_lands_fewer_steep_cells(tmp_path, capsys):
    held, ended = tmp_path / "held.yaml", tmp_path / "ended.yaml"
    grid = ["--slope-min", "30", "--slope-max", "50", "--slope-step", "10", "--speed-step", "1.0", "--quiet"]
    grid += ["--speed-min", "1.0"]
    assert main(["table", "--out", str(held), *grid]) == 0
    assert main(["table", "--out", str(ended), *grid, "--reverse-duration", "0.6"]) == 0
    h, e = LookupTable.load(held), LookupTable.load(ended)
    assert "reverse_duration" not in h.strategy  # held: the files read as before
    assert e.strategy["reverse_duration"] == 0.6 and e.strategy["reverse_ramp"] == 0.0
    assert "held 0.6 s, then stopped" in e.strategy["description"]
    landed = ("ideal", "under_used", "end_of_travel")
    # 50 deg: held by the thrust it lands; once a step ends the thrust it cannot (tan 50 > mu_k)
    assert all(o in landed for o in h.cells["outcome"][2])
    assert not any(o in landed for o in e.cells["outcome"][2])


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--reverse-ramp", "1"], "--reverse-ramp needs --reverse-duration"),
        (["--reverse-duration", "0"], "reverse_duration"),
        (["--reverse-duration", "0.6", "--reverse-ramp", "-1"], "reverse_ramp"),
    ],
)
def test_a_bad_thrust_end_is_an_error_message_before_any_work(extra, message, tmp_path, capsys):
    assert main(["table", "--out", str(tmp_path / "t.yaml"), *GRID, *extra]) == 1
    assert message in capsys.readouterr().err
    assert not (tmp_path / "t.yaml").exists()
