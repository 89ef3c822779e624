"""The command line answers at once because parsing imports no science: checked by what a fresh
process has imported, not by a clock (benchmarks/cli_latency.py measures the times)."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys

import pytest

HEAVY = ("numpy", "numba", "scipy", "matplotlib", "tqdm", "cma", "lupa", "slopelander.model")

PARSE = """
import json, sys
import slopelander.cli
parser = slopelander.cli.build_parser()
for argv in json.loads(sys.argv[1]):
    try:
        parser.parse_args(argv)
    except SystemExit:
        pass
print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] in {heavy} or m in {heavy})))
"""

ARGVS = [
    ["--help"],
    ["--version"],
    ["demo", "--slope", "20"],
    ["land", "--connect", "tcp:127.0.0.1:5760", "--legs-port", "/tmp/legboard", "--slope", "35"],
    ["legs", "status", "--legs-port", "/dev/ttyACM0"],
    ["simulate", "--slope", "35", "--reverse"],
    ["simulate", "--slope", "x"],
    ["params"],
    ["map", "rvt", "--out", "maps"],
    ["table", "--out", "t.yaml"],
    ["lookup", "--slope", "35", "--speed", "1.5"],
    ["synth", "--out", "drops"],
    ["compare", "drops"],
    ["fit", "drops", "--fit", "ground_damping"],
    ["diagnose", "drops"],
    ["steps", "drops", "--add", "leg_flex"],
    ["map", "--help"],
    ["fit", "--help"],
]


def _fresh(code: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, env=env, timeout=120
    )


def test_importing_the_cli_and_parsing_every_command_imports_no_science() -> None:
    done = _fresh(PARSE.format(heavy=set(HEAVY)), json.dumps(ARGVS))
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(done.stdout.strip().splitlines()[-1]) == []


@pytest.mark.parametrize(
    "argv",
    [
        ["land", "--connect", "tcp:127.0.0.1:9", "--legs-port", "/nonexistent/port", "--slope", "35"],
        ["land", "--connect", "tcp:127.0.0.1:9", "--legs-port", "/dev/null", "--slope", "70"],
        ["land", "--connect", "garbage:foo", "--legs-port", "/dev/null", "--slope", "35"],
        ["legs", "status", "--legs-port", "/nonexistent/port"],
        ["lookup", "--slope", "75", "--speed", "1.5"],
    ],
    ids=lambda a: " ".join(a[:2]),
)
def test_the_refusals_of_the_flying_commands_import_no_science(argv: list[str]) -> None:
    science = set(HEAVY) - {"numpy"}  # the lookup table is numpy, and so is the controller
    code = (
        "import sys; from slopelander.cli import main; rc = main(sys.argv[1:]); "
        f"print(sorted(m for m in sys.modules if m.split('.')[0] in {science!r} or m in {science!r})); "
        "sys.exit(rc)"
    )
    done = _fresh(code, *argv)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "Traceback" not in done.stderr and done.stderr.count("\n") == 1, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_the_simulate_defaults_written_out_are_the_models() -> None:
    from slopelander.commands.simulate import _D
    from slopelander.model import LandingConditions

    model = dataclasses.asdict(LandingConditions())
    assert vars(_D) == {k: model[k] for k in vars(_D)}


def test_the_map_kinds_written_out_are_the_reports() -> None:
    from slopelander.commands.map import MAP_KINDS as CLI_KINDS
    from slopelander.envelope.reports import MAP_KINDS

    assert CLI_KINDS == MAP_KINDS


def test_a_named_command_imports_only_its_own_module() -> None:
    """`slopelander simulate ...` builds the simulate parser alone: the leg driver, pyserial and
    the other commands' modules are not imported (the whole parser is built for `--help`)."""
    code = """
import json, sys
from slopelander.cli import main
try:
    main(sys.argv[1:])
except SystemExit as exc:
    print(json.dumps(sorted(m for m in sys.modules if m.startswith("slopelander.") or m == "serial")))
    sys.exit(exc.code)
"""
    done = _fresh(code, "simulate", "--slope", "x")
    assert done.returncode == 2 and "invalid float value: 'x'" in done.stderr, done.stderr
    imported = set(json.loads(done.stdout.strip().splitlines()[-1]))
    assert "slopelander.commands.simulate" in imported
    others = {"serial", "slopelander.legs.driver", "slopelander.commands.land", "slopelander.commands.fit"}
    assert not imported & others, imported & others


@pytest.mark.parametrize("argv", [["simulate", "--help"], ["legs", "set", "--help"], ["fit", "--help"]])
def test_a_command_alone_parses_and_helps_as_in_the_whole_parser(argv: list[str], capsys) -> None:
    from slopelander.cli import build_parser, named_command

    texts = []
    for parser in (build_parser(), build_parser(named_command(argv))):
        with pytest.raises(SystemExit):
            parser.parse_args(argv)
        texts.append(capsys.readouterr().out)
    assert texts[0] == texts[1] and "usage: slopelander " + argv[0] in texts[0]
    assert named_command(["--help"]) is None and named_command(["nosuch"]) is None


def test_simulate_from_its_own_command_line_ends_without_teardown_its_output_complete(tmp_path) -> None:
    """The interpreter's teardown (numba, LLVM, numpy: 0.3-0.4 s of CPU) is skipped once
    `simulate` has finished: an exit handler does not run, yet every line is printed through
    the pipe, the CSV is whole and the exit status is the command's."""
    csv_path = tmp_path / "t.csv"
    code = (
        "import atexit, sys; atexit.register(lambda: print('TEARDOWN')); "
        "from slopelander.cli import main; sys.exit(main())"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    argv = ["simulate", "--slope", "20", "--csv", str(csv_path)]
    done = subprocess.run(
        [sys.executable, "-c", code, *argv], capture_output=True, text=True, env=env, timeout=600
    )
    assert done.returncode == 0, done.stderr
    assert "TEARDOWN" not in done.stdout
    lines = done.stdout.splitlines()
    assert lines[0].startswith("landing: 20 deg slope") and lines[-1] == f"trajectory: {csv_path}", lines
    rows = csv_path.read_text().splitlines()
    assert rows[0].startswith("t_s,") and len(rows) > 100 and rows[-1].count(",") == 6
    # called with its arguments (a test, another program) it returns as before
    inproc = subprocess.run(
        [sys.executable, "-c", code.replace("main()", "main(sys.argv[1:])"), *argv],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert inproc.returncode == 0 and inproc.stdout.rstrip().endswith("TEARDOWN"), inproc.stdout
