"""Every input file a user or a lab hands slopelander, mutated by hypothesis: a loader either
accepts the file or fails with its own error type whose message names the file — never a
traceback from deep inside (a KeyError, a TypeError, a numpy error), never half a file applied.

Mutations start from the shipped valid files: a leaf replaced by a hostile value, a key deleted,
a value wrapped in a list or a mapping, the text cut short or a byte inserted."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from slopelander.controller.config import load_config
from slopelander.controller.table import LookupTable
from slopelander.errors import SlopelanderError
from slopelander.legs.calibration import load_calibration
from slopelander.model.parameters import ModelParams
from slopelander_sitl.vehicle.params import ParamError, load_parm
from slopelander_sitl.vehicle.scenario import ScenarioError, load_scenario

SRC = Path(__file__).resolve().parents[2] / "src" / "slopelander"
REPO = SRC.parents[1]
SCENARIO = {
    "slope_deg": 35.0,
    "seed": 3,
    "start_on": "pad",
    "rc": [{"t": 1.0, "channels": {3: 1500}}, {"t": 2.0, "channels": {8: 1900}}],
    "faults": [{"kind": "rangefinder_dropout", "start": 1.0, "end": 2.0}],
    "wind": {
        "steady": {"fx_n": 0.5, "fz_n": 0.0},
        "gusts": [{"t_s": 3.0, "duration_s": 2.0, "fx_n": 4.0, "fz_n": -1.0}],
        "random_gusts": {"count": 3, "max_n": 2.0, "from_s": 5.0, "to_s": 20.0, "duration_s": 1.0},
    },
}
LOADERS = {
    "config": (SRC / "controller" / "default_config.yaml", load_config, (SlopelanderError,)),
    "table": (SRC / "controller" / "default_table.yaml", LookupTable.load, (SlopelanderError,)),
    "calibration": (SRC / "legs" / "default_calibration.yaml", load_calibration, (SlopelanderError,)),
    "parameters": (SRC / "model" / "default_parameters.yaml", ModelParams.load, (SlopelanderError,)),
    "scenario": (yaml.safe_dump(SCENARIO), load_scenario, (ScenarioError,)),
}
HOSTILE = [None, "", "x", -1, 0, 1e308, -1e308, math.nan, math.inf, True, [], {}, [1, "a"], {"a": 1}]


def paths(node, prefix=()):
    """Every path to a value in a YAML tree."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from paths(v, (*prefix, i))


def mutate_tree(doc, path, op: str, value):
    if not path:
        return value
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    key = path[-1]
    if op == "delete":
        del parent[key]
    elif op == "wrap":
        parent[key] = [parent[key]]
    elif op == "nest":
        parent[key] = {"value": parent[key]}
    else:
        parent[key] = value
    return doc


@st.composite
def mutated_text(draw, original: str) -> str:
    if draw(st.integers(0, 3)) == 0:  # a text-level accident
        i = draw(st.integers(0, len(original)))
        if draw(st.booleans()):
            return original[:i]
        return (
            original[:i]
            + draw(st.sampled_from(["\0", "\t", ":", "- ", "[", "{", "\n  x: 1\n", "é"]))
            + original[i:]
        )
    doc = yaml.safe_load(original)
    all_paths = list(paths(doc))
    path = draw(st.sampled_from(all_paths))
    op = draw(st.sampled_from(["replace", "replace", "replace", "delete", "wrap", "nest"]))
    value = draw(st.sampled_from(HOSTILE))
    if op == "delete" and not path:
        op = "replace"
    return yaml.safe_dump(mutate_tree(doc, path, op, value), allow_unicode=True)


@pytest.mark.parametrize("kind", sorted(LOADERS))
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_mutated_file_loads_or_fails_naming_the_file(kind: str, data, tmp_path: Path) -> None:
    source, load, errors = LOADERS[kind]
    original = source.read_text() if isinstance(source, Path) else source
    text = data.draw(mutated_text(original))
    path = tmp_path / f"mutated-{kind}.yaml"
    path.write_text(text)
    try:
        load(path)
    except errors as exc:
        assert path.name in str(exc), f"{type(exc).__name__} does not name the file: {exc}"


PARM = (REPO / "firmware_params" / "sitl.parm").read_text()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_mutated_parameter_file_loads_or_names_file_and_line(data, tmp_path: Path) -> None:
    lines = PARM.splitlines()
    i = data.draw(st.integers(0, len(lines) - 1))
    lines[i] = data.draw(
        st.one_of(
            st.sampled_from(
                ["ANGLE_MAX", "ANGLE_MAX 1 2", "ANGLE_MAX,abc", "ANGLE_MAX nan", ",", "  ", "#", "\0"]
            ),
            st.text(max_size=30).filter(lambda s: "\n" not in s and "\r" not in s),
        )
    )
    path = tmp_path / "mutated.parm"
    path.write_text("\n".join(lines) + "\n")
    try:
        load_parm(path)
    except ParamError as exc:
        assert path.name in str(exc)
