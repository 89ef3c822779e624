"""``slopelander params --out`` and override files that hold only what they change."""

from __future__ import annotations

from pathlib import Path

import pytest

from slopelander.cli import main
from slopelander.model import Model, ModelParams, ParameterError
from slopelander.model.parameters import PARAMETER_NAMES, SPECS


def test_the_dump_loads_back_as_the_defaults_and_comments_every_parameter(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "params.yaml"
    assert main(["params", "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    loaded, default = ModelParams.load(out), ModelParams.default()
    assert {n: (v.value, v.unit, v.provenance) for n, v in loaded.values.items()} == {
        n: (v.value, v.unit, v.provenance) for n, v in default.values.items()
    }
    assert loaded.effects == default.effects
    text = out.read_text()
    for spec in SPECS:
        assert f"  # {spec.description}; {spec.unit}, allowed " in text
    assert "keep only the parameters you change" in text


def test_the_dump_goes_to_standard_output_without_a_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["params", "--out"]) == 0
    text = capsys.readouterr().out
    assert ModelParams.from_yaml_text(text).values["body_mass"].value == 1.502


def test_the_dump_does_not_overwrite_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "mine.yaml"
    out.write_text("precious\n")
    assert main(["params", "--out", str(out)]) == 1
    assert "exists" in capsys.readouterr().err and out.read_text() == "precious\n"
    assert main(["params", "--out", str(tmp_path / "no" / "p.yaml")]) == 1
    assert "does not exist" in capsys.readouterr().err


def test_an_override_file_may_hold_only_what_it_changes(tmp_path: Path) -> None:
    path = tmp_path / "override.yaml"
    path.write_text(
        "schema: slopelander.model-parameters/1\n"
        "parameters:\n"
        "  ground_damping: 400\n"
        "  body_mass: {value: 1.6, unit: kg, provenance: identified, note: weighed}\n"
    )
    p, d = ModelParams.load(path), ModelParams.default()
    assert p["ground_damping"] == 400.0 and p.values["ground_damping"].provenance == "assumed"
    assert p["body_mass"] == 1.6 and p.values["body_mass"].note == "weighed"
    assert all(p[n] == d[n] for n in PARAMETER_NAMES if n not in ("ground_damping", "body_mass"))
    assert p.effects == d.effects
    assert Model.from_file(str(path)).params["body_mass"] == 1.6


def test_an_override_with_its_own_effects_keeps_them(tmp_path: Path) -> None:
    path = tmp_path / "o.yaml"
    path.write_text("schema: slopelander.model-parameters/1\nparameters: {}\neffects: [leg_flex]\n")
    assert ModelParams.load(path).effects == ("leg_flex",)


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ("  body_mass: {value: 1.6, unit: g}\n", "unit must be 'kg'"),
        ("  body_mass: heavy\n", "must be a number or a mapping"),
        ("  body_mas: 1.6\n", "unknown parameter"),
        ("  body_mass: -1\n", "outside"),
    ],
)
def test_an_override_is_still_checked(tmp_path: Path, body: str, words: str) -> None:
    path = tmp_path / "o.yaml"
    path.write_text("schema: slopelander.model-parameters/1\nparameters:\n" + body)
    with pytest.raises(ParameterError, match=words):
        ModelParams.load(path)


def test_simulate_flies_an_override_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "o.yaml"
    path.write_text("schema: slopelander.model-parameters/1\nparameters:\n  friction_kinetic: 0.3\n")
    assert main(["simulate", "--slope", "30", "--params", str(path)]) == 0
    assert capsys.readouterr().out.startswith("landing: 30 deg slope")
