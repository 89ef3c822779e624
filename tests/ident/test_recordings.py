"""Drop recordings: round trip, converter, and every malformed case naming file, line and field."""

import json
import math
import shutil

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from slopelander.ident.recording import (
    Convention,
    Drop,
    RecordingError,
    convert,
    load_dataset,
    load_drop,
    write_drop,
)
from slopelander.model import LandingConditions, Outcome


def _drop(name: str = "d0") -> Drop:
    t = np.arange(-0.01, 0.2, 0.005)
    rng = np.random.default_rng(3)
    states = rng.normal(0, 0.1, (len(t), 6))
    cond = LandingConditions(slope_deg=20.0, speed=2.1, tau_up=1.1, tau_down=1.7)
    return Drop(name, t, states, cond, Outcome.IDEAL, "unit test")


def test_round_trip(tmp_path):
    d = _drop()
    write_drop(d, tmp_path)
    back = load_dataset(tmp_path)
    assert len(back) == 1
    b = back[0]
    assert b.name == "d0" and b.conditions == d.conditions and b.outcome is Outcome.IDEAL
    np.testing.assert_allclose(b.t, d.t, atol=1e-6)
    np.testing.assert_allclose(b.states, d.states, rtol=1e-6, atol=1e-9)


def test_units_in_the_header_are_converted_to_si(tmp_path):
    write_drop(_drop(), tmp_path)
    p = tmp_path / "d0.csv"
    lines = p.read_text().splitlines()
    lines[0] = "time [ms],x [mm],z [m],pitch [deg],x_rate [mm/s],z_rate [m/s],pitch_rate [deg/s]"
    lines[1] = "-10,1000,1,90,1000,1,180"
    p.write_text("\n".join(lines) + "\n")
    d = load_drop(p)
    np.testing.assert_allclose(d.t[0], -0.01)
    np.testing.assert_allclose(d.states[0], [1.0, 1.0, math.pi / 2, 1.0, 1.0, math.pi])


def _corrupt_csv(tmp_path, line: int, text: str):
    write_drop(_drop(), tmp_path)
    p = tmp_path / "d0.csv"
    lines = p.read_text().splitlines()
    lines[line - 1] = text
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize(
    ("line", "text", "fieldname", "words"),
    [
        (1, "time [s],x [m],z [m],pitch [rad],x_rate [m/s],z_rate [m/s]", "pitch_rate", "missing column"),
        (
            1,
            "time [s],x [m],z [m],pitch [grad],x_rate [m/s],z_rate [m/s],pitch_rate [rad/s]",
            "pitch",
            "unknown unit 'grad'",
        ),
        (
            1,
            "time [s],x [m],z [m],roll [rad],x_rate [m/s],z_rate [m/s],pitch_rate [rad/s]",
            "roll",
            "unknown column",
        ),
        (5, "0.01,0,0,nan,0,0,0", "pitch", "not a finite number"),
        (6, "0.01,0,0,0,0,abc,0", "z_rate", "'abc' is not a number"),
        (7, "-0.02,0,0,0,0,0,0", "time", "time must increase"),
        (8, "0.5,0,0,0,0", "z_rate", "5 cells"),
    ],
)
def test_malformed_csv_names_file_line_field(tmp_path, line, text, fieldname, words):
    p = _corrupt_csv(tmp_path, line, text)
    with pytest.raises(RecordingError) as err:
        load_dataset(tmp_path)
    msg = str(err.value)
    assert str(p) in msg and f"line {line}" in msg and f"field '{fieldname}'" in msg and words in msg


@pytest.mark.parametrize(
    ("edit", "fieldname", "words"),
    [
        (lambda d: d["conditions"].update(slope_deg=120.0), "conditions.slope_deg", "-75..75"),
        (lambda d: d["conditions"].update(tau_down=-1.0), "conditions.tau_down", "0..10"),
        (lambda d: d["conditions"].update(wind=3.0), "conditions.wind", "unknown condition"),
        (lambda d: d["conditions"].update(speed="fast"), "conditions.speed", "not a number"),
        (lambda d: d["conditions"].pop("speed"), "conditions.speed", "missing"),
        (lambda d: d.update(outcome="crashed"), "outcome", "unknown outcome"),
        (
            lambda d: d.update(outcome={"ideal": True}),
            "outcome",
            "unknown outcome {'ideal': True}; known: ideal",
        ),
        (lambda d: d.update(outcome=["slid"]), "outcome", "unknown outcome ['slid']; known: ideal"),
        (lambda d: d.update(source=["lab", "take 7"]), "source", "must be text, got ['lab', 'take 7']"),
        (lambda d: d["conditions"].update(speed=10**400), "conditions.speed", "is beyond any float"),
        (lambda d: d.update(meta=[]), "meta", "must be an object"),
        (
            lambda d: d.update(
                meta={"rates": {"method": "savgol", "window": 5, "polyorder": 2, "dt": 10**400}}
            ),
            "meta.rates",
            '"savgol" needs',
        ),
        (
            lambda d: d.update(
                meta={"rates": {"method": "savgol", "window": 5, "polyorder": True, "dt": 0.005}}
            ),
            "meta.rates",
            '"savgol" needs',
        ),
        (lambda d: d.update(schema="other/1"), "schema", "must be"),
    ],
)
def test_impossible_conditions_name_file_line_field(tmp_path, edit, fieldname, words):
    write_drop(_drop(), tmp_path)
    p = tmp_path / "d0.json"
    doc = json.loads(p.read_text())
    edit(doc)
    p.write_text(json.dumps(doc, indent=2))
    with pytest.raises(RecordingError) as err:
        load_dataset(tmp_path)
    msg = str(err.value)
    assert str(p) in msg and f"field '{fieldname}'" in msg and words in msg
    if fieldname.startswith("conditions.") and words != "missing":
        key = fieldname.split(".")[1]
        line = next(i for i, s in enumerate(p.read_text().splitlines(), 1) if f'"{key}"' in s)
        assert f"line {line}" in msg


def test_missing_sidecar_and_empty_folder(tmp_path):
    with pytest.raises(RecordingError, match="holds no drop"):
        load_dataset(tmp_path)
    write_drop(_drop(), tmp_path)
    (tmp_path / "d0.json").unlink()
    with pytest.raises(RecordingError, match=r"d0\.json.*missing"):
        load_dataset(tmp_path)


def test_converter_undoes_a_foreign_frame(tmp_path):
    """A lab export with x uphill along the slope, nose-down pitch in degrees, millimetres and
    its own column names loads as the original drop."""
    d = _drop()
    a = math.radians(d.conditions.slope_deg)
    c, s = math.cos(a), math.sin(a)
    # our frame -> slope frame (x along the slope downhill, z normal), then x uphill, nose down
    xs = c * d.states[:, 0] - s * d.states[:, 1]
    zs = s * d.states[:, 0] + c * d.states[:, 1]
    vxs = c * d.states[:, 3] - s * d.states[:, 4]
    vzs = s * d.states[:, 3] + c * d.states[:, 4]
    pitch = -(d.states[:, 2] + a)
    rate = -d.states[:, 5]
    src = tmp_path / "lab" / "take7.csv"
    src.parent.mkdir()
    rows = ["Time,PosX,PosZ,Pitch,VelX,VelZ,PitchRate"]
    for i, t in enumerate(d.t + 0.3):
        rows.append(
            ",".join(
                f"{v:.9g}"
                for v in (
                    t,
                    -1000 * xs[i],
                    1000 * zs[i],
                    math.degrees(pitch[i]),
                    -1000 * vxs[i],
                    1000 * vzs[i],
                    math.degrees(rate[i]),
                )
            )
        )
    src.write_text("\n".join(rows) + "\n")
    conv = Convention(
        x_uphill=True,
        pitch_nose_down=True,
        slope_frame=True,
        time_offset=-0.3,
        columns={
            "time": "Time",
            "x": "PosX",
            "z": "PosZ",
            "pitch": "Pitch",
            "x_rate": "VelX",
            "z_rate": "VelZ",
            "pitch_rate": "PitchRate",
        },
    )
    units = {
        "time": "s",
        "x": "mm",
        "z": "mm",
        "pitch": "deg",
        "x_rate": "mm/s",
        "z_rate": "mm/s",
        "pitch_rate": "deg/s",
    }
    out = convert(src, d.conditions, tmp_path / "ds", conv, units=units)
    back = load_drop(out)
    np.testing.assert_allclose(back.t, d.t, atol=1e-6)
    np.testing.assert_allclose(back.states, d.states, atol=1e-6)
    assert "take7.csv" in back.source


def test_converter_reports_the_foreign_column(tmp_path):
    src = tmp_path / "take.csv"
    src.write_text("Time,PosX,PosZ,Pitch,VelX,VelZ,PitchRate\n0,1,1,1,1,1,1\n0.1,1,1,x,1,1,1\n")
    conv = Convention(
        columns={
            "time": "Time",
            "x": "PosX",
            "z": "PosZ",
            "pitch": "Pitch",
            "x_rate": "VelX",
            "z_rate": "VelZ",
            "pitch_rate": "PitchRate",
        }
    )
    units = {
        "time": "s",
        "x": "m",
        "z": "m",
        "pitch": "rad",
        "x_rate": "m/s",
        "z_rate": "m/s",
        "pitch_rate": "rad/s",
    }
    with pytest.raises(RecordingError) as err:
        convert(src, LandingConditions(), tmp_path / "ds", conv, units=units)
    assert str(src) in str(err.value) and "line 3" in str(err.value) and "'Pitch'" in str(err.value)
    shutil.rmtree(tmp_path / "ds", ignore_errors=True)


HOSTILE = [
    None,
    "",
    "x",
    -1,
    0,
    2.5,
    10**400,
    -(10**400),
    True,
    [],
    {},
    [1, "a"],
    {"a": 1},
    {"method": "savgol"},
]


def _json_paths(node, prefix=()):
    """Every path to a value in a JSON tree, the root's included."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _json_paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _json_paths(v, (*prefix, i))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_wrong_typed_value_anywhere_in_a_sidecar_is_refused_naming_the_file(data, tmp_path):
    """Any value of a drop's JSON replaced by one of another type (or a hostile one): the drop
    loads, or load_drop raises its own RecordingError naming its file, never a bare error."""
    d = _drop()
    t = np.round(np.arange(-0.01, 0.2, 0.005), 6)
    rates = data.draw(
        st.sampled_from(
            [
                {"method": "measured"},
                {"method": "lsq_slope", "window": 5},
                {"method": "savgol", "window": 7, "polyorder": 2, "dt": 0.005},
            ]
        )
    )
    d = Drop(
        "d0",
        t,
        d.states[: len(t)],
        d.conditions,
        d.outcome,
        d.source,
        {"rates": rates, "noise": {"x": 0.001}},
    )
    write_drop(d, tmp_path)
    side = tmp_path / "d0.json"
    doc = json.loads(side.read_text())
    path = data.draw(st.sampled_from(list(_json_paths(doc))))
    value = data.draw(
        st.one_of(st.sampled_from(HOSTILE), st.lists(st.integers(), max_size=3), st.text(max_size=8))
    )
    if path:
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        parent[path[-1]] = value
    else:
        doc = value
    side.write_text(json.dumps(doc, indent=2))
    try:
        load_drop(tmp_path / "d0.csv")
    except RecordingError as exc:  # names the JSON, or the CSV when the JSON's rates do not fit its frames
        assert str(side) in str(exc) or str(tmp_path / "d0.csv") in str(exc), exc
