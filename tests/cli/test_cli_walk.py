"""A property test that walks the command line with generated arguments and small generated
files (lookup tables, parameter overrides, drop recordings): whatever it is given, a command ends
with a result, a one-line error or an argparse usage message -- never a traceback. Cheap commands
only (no map figures, no processes), and sizes are capped so that a generated grid or step stays
small."""

from __future__ import annotations

import contextlib
import copy
import io
import json
import tempfile
from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from slopelander.cli import main
from slopelander.controller.table import DEFAULT_TABLE

NUMBERS = st.one_of(
    st.sampled_from(["0", "1.5", "-1", "35", "60", "75", "1e9", "nan", "inf", "-inf", "abc", ""]),
    st.floats(-100, 100, allow_nan=False).map(lambda v: f"{v:g}"),
)
SMALL_STEPS = st.sampled_from(["20", "30", "45", "0", "-5", "nan", "x"])
SPEED_BOUNDS = st.sampled_from(["0.5", "1", "2", "3", "-1", "nan", "16"])
DT = st.sampled_from(["0.001", "0.0005", "0", "-1", "nan", "inf", "1", "dt"])
EFFECTS = st.sampled_from(["rotors", "leg_flex", "foot_stiction", "rigid_gear", "wind", ""])

_TABLE_DOC = yaml.safe_load(Path(DEFAULT_TABLE).read_text())
_SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True), st.text(max_size=6)
)


@st.composite
def table_text(draw) -> str:
    """The shipped table with one thing broken: a cell, a row, a field, the axes or the schema."""
    doc = copy.deepcopy(_TABLE_DOC)
    what = draw(st.sampled_from(["cell", "row", "drop", "axis", "schema", "whole"]))
    field = draw(st.sampled_from(sorted(doc["cells"])))
    rows = doc["cells"][field]
    i = draw(st.integers(0, len(rows) - 1))
    if what == "cell":
        rows[i][draw(st.integers(0, len(rows[i]) - 1))] = draw(_SCALARS)
    elif what == "row":
        rows[i] = rows[i][: draw(st.integers(0, len(rows[i]) - 1))]
    elif what == "drop":
        del doc["cells"][field]
    elif what == "axis":
        doc["axes"][draw(st.sampled_from(["slope_deg", "speed"]))] = draw(st.lists(_SCALARS, max_size=4))
    elif what == "schema":
        doc["schema"] = draw(_SCALARS)
    else:
        return draw(st.text(max_size=40))
    return yaml.safe_dump(doc, sort_keys=False)


@st.composite
def params_text(draw) -> str:
    """A parameter override: some entries, each a number, a mapping or junk."""
    names = st.sampled_from(
        [
            "body_mass",
            "ground_damping",
            "friction_kinetic",
            "friction_static",
            "leg_travel_deg",
            "gravity",
            "wing_area",
        ]
    )
    entry = st.one_of(
        _SCALARS,
        st.fixed_dictionaries(
            {"value": _SCALARS},
            optional={
                "unit": st.sampled_from(["kg", "g", "N*s/m", ""]),
                "provenance": st.sampled_from(["paper", "guess"]),
            },
        ),
    )
    doc: dict = {"parameters": draw(st.dictionaries(names, entry, max_size=3))}
    if draw(st.booleans()):
        doc["schema"] = draw(st.sampled_from(["slopelander.model-parameters/1", "other/1"]))
    if draw(st.booleans()):
        doc["effects"] = draw(st.lists(EFFECTS, max_size=2))
    return yaml.safe_dump(doc) if draw(st.booleans()) else draw(st.text(max_size=30))


HEADER = "time [s],x [m],z [m],pitch [rad],x_rate [m/s],z_rate [m/s],pitch_rate [rad/s]"
CELLS = st.one_of(
    st.floats(-3, 3, allow_nan=False).map(lambda v: f"{v:.4g}"),
    st.sampled_from(["nan", "", "x", "1e400", "-0"]),
)


@st.composite
def drop_files(draw) -> tuple[str, str]:
    """A drop's CSV and JSON: a header that may lose a column or a unit, rows that may be ragged,
    unordered or not numbers, conditions that may be missing or out of range."""
    header = draw(
        st.sampled_from(
            [
                HEADER,
                HEADER.replace("[s]", "[h]"),
                HEADER.rsplit(",", 1)[0],
                HEADER.replace("pitch [rad]", "yaw [rad]"),
                "",
            ]
        )
    )
    n = draw(st.integers(0, 6))
    times = sorted(draw(st.lists(st.floats(-0.05, 0.3, allow_nan=False), min_size=n, max_size=n)))
    if draw(st.booleans()):
        times = times[::-1]
    rows = [",".join([f"{t:.4f}", *draw(st.lists(CELLS, min_size=5, max_size=7))]) for t in times]
    conditions = draw(
        st.fixed_dictionaries(
            {},
            optional={
                "slope_deg": st.sampled_from([0, 20, 80, "steep"]),
                "speed": st.sampled_from([0.5, 2.0, -1, 20]),
                "tau_up": st.sampled_from([1.1, -3]),
                "wind": st.just(1),
            },
        )
    )
    doc = {
        "schema": draw(st.sampled_from(["slopelander.drop/1", "slopelander.drop/9"])),
        "conditions": conditions,
        **({"outcome": draw(st.sampled_from(["ideal", "crashed", 3]))} if draw(st.booleans()) else {}),
    }
    side = json.dumps(doc) if draw(st.booleans()) else draw(st.text(max_size=20))
    return "\n".join([header, *rows]) + "\n", side


def _path(draw, root: Path, kind: str) -> str:
    """An input file, an output place, or something that is neither."""
    choice = draw(st.sampled_from(["file", "missing", "folder", "missing_parent", "new"]))
    if choice == "file":
        p = root / f"in{draw(st.integers(0, 9))}.yaml"
        p.write_text(draw(table_text() if kind == "table" else params_text()))
        return str(p)
    return {
        "missing": str(root / "absent.yaml"),
        "folder": str(root),
        "missing_parent": str(root / "no" / "such" / "x.yaml"),
        "new": str(root / f"out{draw(st.integers(0, 9))}.yaml"),
    }[choice]


def _argv(draw, root: Path) -> list[str]:
    command = draw(st.sampled_from(["lookup", "params", "simulate", "table", "legs", "compare", "top"]))
    opt = draw  # shorthand

    def maybe(flag: str, value) -> list[str]:
        return [flag, opt(value)] if opt(st.booleans()) else []

    if command == "top":
        return opt(st.sampled_from([[], ["--version"], ["--help"], ["nonsense"], ["lookup", "--help"]]))
    if command == "lookup":
        slope = opt(st.one_of(st.floats(0, 60).map(lambda v: f"{v:g}"), NUMBERS))
        speed = opt(st.one_of(st.floats(0.5, 3).map(lambda v: f"{v:g}"), NUMBERS))
        return [
            "lookup",
            "--slope",
            slope,
            "--speed",
            speed,
            *(["--table", _path(draw, root, "table")] if opt(st.booleans()) else []),
        ]
    if command == "params":
        argv = ["params"]
        if opt(st.booleans()):
            argv += ["--out"] + ([_path(draw, root, "out")] if opt(st.booleans()) else [])
        if opt(st.booleans()):
            argv += ["--params", _path(draw, root, "params")]
        return argv
    if command == "simulate":
        argv = ["simulate"]
        for flag in (
            "--slope",
            "--speed",
            "--pitch",
            "--pitch-rate",
            "--tau-up",
            "--tau-down",
            "--angle-up",
            "--angle-down",
            "--reverse-percent",
            "--horizontal-speed",
        ):
            argv += maybe(flag, NUMBERS)
        argv += maybe("--dt", DT)
        argv += opt(st.sampled_from([[], ["--reverse"], ["--rigid"], ["--reverse", "--rigid"]]))
        if opt(st.booleans()):
            argv += ["--without", *opt(st.lists(EFFECTS, min_size=1, max_size=2))]
        if opt(st.booleans()):
            argv += ["--params", _path(draw, root, "params")]
        if opt(st.booleans()):
            argv += ["--csv", _path(draw, root, "out")]
        return argv
    if command == "table":
        return [
            "table",
            "--out",
            _path(draw, root, "out"),
            "--quiet",
            "--slope-step",
            opt(SMALL_STEPS),
            "--speed-step",
            opt(st.sampled_from(["1", "0", "nan"])),
            "--speed-min",
            opt(SPEED_BOUNDS),
            "--speed-max",
            opt(SPEED_BOUNDS),
            *maybe("--strategy", st.sampled_from(["rvt", "angle", "wrong"])),
        ]
    if command == "compare":
        dataset = root / "drops"
        dataset.mkdir()
        for i in range(draw(st.integers(0, 2))):
            csv_text, side = draw(drop_files())
            (dataset / f"drop{i}.csv").write_text(csv_text)
            if draw(st.booleans()) or i == 0:
                (dataset / f"drop{i}.json").write_text(side)
        report = ["--out", _path(draw, root, "out")] if opt(st.booleans()) else []
        return ["compare", str(dataset), *report]
    return [
        "legs",
        "angle",
        "--legs-port",
        str(root / "no-such-port"),
        "--timeout",
        "0.5",
        *maybe("--angle-up", NUMBERS),
        *maybe("--angle-down", NUMBERS),
    ]


def _run(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse: --help/--version (0) or a usage error (2)
            code = exc.code if isinstance(exc.code, int) else 2
            assert code in (0, 2), (argv, exc.code)
            return code, err.getvalue()
    return code, err.getvalue()


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_no_command_line_ends_in_a_traceback(data) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        argv = _argv(data.draw, Path(tmp))
        code, err = _run(argv)  # an exception other than SystemExit fails the test here
    assert "Traceback" not in err, (argv, err)
    assert code in (0, 1, 2, 130), (argv, code)
    if code == 1:
        lines = err.strip().splitlines()
        assert lines and lines[-1].startswith("slopelander "), (argv, err)
        assert "error:" in lines[-1], (argv, err)
