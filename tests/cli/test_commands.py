"""The commands as one set: every ``--help`` answers, one concept has one option name in every
command (docs/commands.md, "Option names"), and each old spelling still works with its notice."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

from slopelander.cli import build_parser, main
from slopelander.commands.options import CommandParser

ROOT = Path(__file__).resolve().parents[2]

#: every command as a user types it (the ``legs`` actions one by one)
COMMANDS = [
    *("demo", "land", "legs", "simulate", "params", "map", "table", "lookup"),
    *("import", "synth", "compare", "fit", "diagnose", "steps"),
    *("legs-status", "legs-calibrate", "legs-set", "legs-loosen", "legs-angle"),
]

LEGS = {"legs status", "legs calibrate", "legs set", "legs loosen", "legs angle"}
LEGS_TALK = LEGS - {"legs calibrate"}
MODEL = {"simulate", "synth", "compare", "fit", "diagnose", "steps"}
SWEEP = {"map", "table"}
SEARCH = {"fit", "diagnose", "steps"}

#: concept -> (its one option name, the commands that have it); every other command has no
#: visible option of that name
CONCEPTS: dict[str, tuple[str, set[str]]] = {
    "the leg board's serial device": ("--legs-port", {"land"} | LEGS),
    "the leg board's baud rate": ("--legs-baud", LEGS),
    "the autopilot's MAVLink connection": ("--connect", {"land"}),
    "the baud rate of a serial autopilot connection": ("--baud", {"land"}),
    "a YAML settings file": ("--config", {"land"}),
    "the presets a map or table flies": ("--strategy", SWEEP),
    "the lookup table file": ("--table", {"land", "lookup", "legs status", "legs set", "demo"}),
    "the leg board's calibration file": ("--calibration", {"land"} | LEGS_TALK),
    "the model's parameter file": ("--params", MODEL | SWEEP | {"params"}),
    "effects switched off": ("--without", MODEL),
    "a file of user effects": ("--effects-file", MODEL),
    "the command's output": (
        "--out",
        {"land", "params", "map", "table", "synth", "import", "compare", "fit", "legs calibrate", "demo"},
    ),
    "a picture": ("--plot", {"simulate", "steps"}),
    "the figures as JSON": ("--json", {"compare", "diagnose"}),
    "the landing slope": ("--slope", {"land", "simulate", "lookup", "legs set", "compare", "demo"}),
    "the vertical impact speed": ("--speed", {"simulate", "lookup", "legs set"}),
    "the lowest slope of a range": ("--slope-min", SWEEP | {"synth"}),
    "the highest slope of a range": ("--slope-max", SWEEP | {"synth"}),
    "the lowest speed of a range": ("--speed-min", SWEEP | {"synth"}),
    "the highest speed of a range": ("--speed-max", SWEEP | {"synth"}),
    "the uphill legs' friction torque": ("--tau-up", {"simulate", "compare", "legs set"}),
    "the downhill legs' friction torque": ("--tau-down", {"simulate", "compare", "legs set"}),
    "the uphill leg angle": ("--angle-up", {"simulate", "compare", "legs angle"}),
    "the downhill leg angle": ("--angle-down", {"simulate", "compare", "legs angle"}),
    "reverse thrust commanded": ("--reverse", {"simulate"}),
    "reverse thrust's percent": ("--reverse-percent", {"simulate"}),
    "reverse thrust's delay": ("--reverse-delay", {"simulate"}),
    "reverse thrust held this long": ("--reverse-duration", SWEEP | {"simulate"}),
    "reverse thrust's ramp to zero": ("--reverse-ramp", SWEEP | {"simulate"}),
    "a random seed": ("--seed", SEARCH | {"map", "synth"}),
    "a Dask scheduler": ("--dask", SEARCH | SWEEP),
    "no progress bar": ("--quiet", SEARCH | SWEEP),
    "local processes": ("--workers", SEARCH),
    "repetitions": ("--repeats", SEARCH | {"legs calibrate"}),
    "seconds before giving up": ("--timeout", {"land"} | LEGS_TALK),
    "a parameter's value set": ("--set", MODEL - {"simulate"}),
    "the parameters identified": ("--fit", SEARCH),
    "files of candidate effects": ("--candidates", {"diagnose", "steps"}),
    "the global search's budget": ("--cma-evals", SEARCH),
    "the local search's budget": ("--ls-evals", SEARCH),
    "the global search method": ("--optimizer", SEARCH),
    "how the 95 % intervals are made": ("--intervals", {"fit", "diagnose"}),
    "each drop's clock window": ("--align-ms", SEARCH | {"compare"}),
    "the grid's slope step": ("--slope-step", SWEEP),
    "the grid's speed step": ("--speed-step", SWEEP),
    "continuous torques": ("--refine", SWEEP),
    "the uphill angle searched": ("--optimal-angle", SWEEP),
}

#: the spellings the scheme retired: none is shown by any command any more
RETIRED = [
    *("--legs", "--port", "--record", "--dump", "--report", "--tau", "--angles", "--uphill", "--downhill"),
    *("--rvt", "--rvt-percent", "--rvt-delay", "--rvt-duration", "--rvt-ramp", "--slopes", "--speeds"),
]


def parsers() -> dict[str, argparse.ArgumentParser]:
    """Every command's parser by name (``legs set`` for a legs action)."""
    found: dict[str, argparse.ArgumentParser] = {}

    def walk(parser: argparse.ArgumentParser, name: str) -> None:
        found[name] = parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub, p in action.choices.items():
                    walk(p, f"{name} {sub}".strip())

    walk(build_parser(), "")
    del found[""]
    return found


def visible(parser: argparse.ArgumentParser) -> set[str]:
    return {s for a in parser._actions if a.help is not argparse.SUPPRESS for s in a.option_strings}


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_answers_help_with_a_description_and_its_exit_codes(command, capsys) -> None:
    with pytest.raises(SystemExit) as done:
        main([*command.split("-", 1), "--help"] if command.startswith("legs-") else [command, "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: slopelander {command.replace('-', ' ', 1)}"), out[:80]
    assert "%%" not in out and "%(" not in out, command
    parser = parsers()[command.replace("legs-", "legs ")]
    assert parser.description, f"{command} --help has no description"
    if not command.startswith("legs-"):  # the actions share `legs`'s
        assert "Exit codes:" in " ".join(out.split()), command


def test_legs_help_lists_every_action(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["legs", "--help"])
    out = capsys.readouterr().out
    for action in ("status", "calibrate", "set", "loosen", "angle"):
        assert f"\n    {action} " in out or f"\n    {action}\n" in out, action


def test_the_command_list_is_the_one_documented() -> None:
    assert {c.replace("legs-", "legs ") for c in COMMANDS} == set(parsers())


@pytest.mark.parametrize("concept", CONCEPTS)
def test_one_concept_has_one_option_name_across_the_commands(concept: str) -> None:
    name, where = CONCEPTS[concept]
    have = {command for command, p in parsers().items() if name in visible(p)}
    assert have == where, f"{name} ({concept}): in {sorted(have)}, the scheme says {sorted(where)}"


def test_no_command_shows_a_retired_spelling() -> None:
    shown = {(c, o) for c, p in parsers().items() for o in visible(p) if o in RETIRED}
    assert not shown


def test_every_shown_option_is_in_the_scheme_or_its_commands_own() -> None:
    """An option two commands share is in :data:`CONCEPTS`; one command's own may be anything."""
    named = {name for name, _ in CONCEPTS.values()}
    users: dict[str, set[str]] = {}
    for command, p in parsers().items():
        for option in visible(p) - {"-h", "--help"}:
            users.setdefault(option, set()).add(command)
    shared = {o: c for o, c in users.items() if len(c) > 1 and o not in named}
    # the legs actions share their board options: they are one command's
    shared = {o: c for o, c in shared.items() if not c <= LEGS}
    assert not shared, shared


# A line each command parses, to which an old spelling is added.
BASE = {
    "land": ["--connect", "tcp:127.0.0.1:5760", "--legs-port", "/dev/null"],
    "legs calibrate": ["--legs-port", "/dev/null", "--masses", "0.2", "--lever", "0.1", "--out", "c.yaml"],
    "map": ["rvt", "--out", "maps"],
    "compare": ["drops"],
    "synth": ["--out", "drops"],
}
for _legs in LEGS_TALK:
    BASE[_legs] = ["--legs-port", "/dev/null"]


def _value(action: argparse.Action, i: int) -> list[str]:
    if action.nargs == 0:
        return []
    if action.choices:
        return [sorted(action.choices)[-1]]
    kind = getattr(action.type, "__name__", "")
    return [str(10 + i) if kind in ("int", "parse") else f"{1.25 + i}"]


def renamed_options() -> list[tuple[str, str, tuple[str, ...]]]:
    out = []
    for command, p in parsers().items():
        if isinstance(p, CommandParser):
            out += [(command, old, new) for old, new in p.renamed.items()]
    return sorted(out)


def _id(value: object) -> str:
    return " ".join(value) if isinstance(value, tuple) else str(value)


def test_the_old_spellings_are_the_ones_the_scheme_retired() -> None:
    olds = {old for _, old, _ in renamed_options()}
    assert olds == set(RETIRED) - {"--record"} | {"--baud", "--config"}, olds


@pytest.mark.parametrize(("command", "old", "new"), renamed_options(), ids=_id)
def test_an_old_spelling_does_what_the_new_one_does_with_a_notice(command, old, new, capsys) -> None:
    actions = {s: a for a in parsers()[command]._actions for s in a.option_strings}
    values = [v for i, n in enumerate(new) for v in _value(actions[n], i)]
    line = [*command.split(), *BASE.get(command, [])]
    with_new = [w for i, n in enumerate(new) for w in [n, *_value(actions[n], i)]]
    want = build_parser().parse_args(line + with_new)
    assert capsys.readouterr().err == ""
    got = build_parser().parse_args([*line, old, *values])
    assert vars(got) == vars(want)
    assert got != build_parser().parse_args(line)  # the value did arrive
    now = new[0] if len(new) == 1 else " and ".join(new) + ", one value each"
    err = capsys.readouterr().err.splitlines()
    assert err == [f"slopelander {command}: {old} is now {now} (the old name still works, for now)"]


def test_an_old_spelling_also_works_as_old_equals_value(capsys) -> None:
    got = build_parser().parse_args(["simulate", "--rvt-duration=0.6"])
    assert got.reverse_duration == 0.6
    assert "--rvt-duration is now --reverse-duration" in capsys.readouterr().err


def test_an_old_spelling_on_the_command_line_of_a_real_process(tmp_path) -> None:
    """`legs status --port` as a user's script has it: the notice, then the command's own
    refusal of the device, naming the new option."""
    done = subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "legs", "status", "--port", str(tmp_path / "no-tty")],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 1, done.stderr
    assert (
        lines[0] == "slopelander legs status: --port is now --legs-port (the old name still works, for now)"
    )
    assert len(lines) == 2 and lines[1].startswith("slopelander legs: error: "), lines


def test_a_required_option_given_by_its_old_spelling_counts(capsys) -> None:
    args = build_parser().parse_args(["land", "--connect", "tcp:127.0.0.1:5760", "--legs", "/dev/null"])
    assert args.legs_port == "/dev/null"
    with pytest.raises(SystemExit):
        build_parser().parse_args(["land", "--connect", "tcp:127.0.0.1:5760"])
    assert "the following arguments are required: --legs-port" in capsys.readouterr().err


def test_an_old_spelling_short_of_its_values_is_refused_by_the_new_option(capsys) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["compare", "drops", "--tau", "1.1"])
    assert "argument --tau-down: expected one argument" in capsys.readouterr().err


def test_the_reference_page_gives_every_commands_exit_codes() -> None:
    page = (ROOT / "docs" / "commands.md").read_text()
    table = page[page.index("## Exit codes") :]
    table = table[: table.index("\n## ", 4)] if "\n## " in table[4:] else table
    rows = [line.split("|")[1] for line in table.splitlines() if line.startswith("| `")]
    for command in {c.split("-")[0] for c in COMMANDS}:
        assert any(f"`{command}`" in row for row in rows), command
