"""Parameter files: the shipped one is complete; bad ones name the field at fault."""

import pytest
import yaml

from slopelander.model import EffectError, Model, ModelParams, ParameterError
from slopelander.model.parameters import PARAMETER_NAMES, PROVENANCES


def _doc():
    return ModelParams.default().to_dict()


def _load(tmp_path, doc, name="p.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc) if not isinstance(doc, str) else doc)
    return ModelParams.load(path)


def test_default_file_is_complete_with_provenance():
    p = ModelParams.default()
    assert set(p.values) == set(PARAMETER_NAMES)
    assert all(v.provenance in PROVENANCES for v in p.values.values())
    # Table II values are the defaults
    assert p["body_mass"] == 1.502 and p["flex_stiffness"] == 16.4 and p["ground_damping"] == 437.0
    assert p.values["body_mass"].provenance == "paper"


def test_round_trip(tmp_path):
    p = ModelParams.default().with_values(ground_damping=400.0)
    path = tmp_path / "fit.yaml"
    p.save(path)
    q = ModelParams.load(path)
    assert q["ground_damping"] == 400.0
    assert q.values["ground_damping"].provenance == "identified"
    assert q.effects == p.effects


@pytest.mark.parametrize(
    "edit, field, words",
    [
        (lambda d: d["parameters"]["leg_mass"].pop("value"), "leg_mass", "missing 'value'"),
        (lambda d: d["parameters"]["body_mass"].update(unit="g"), "body_mass", "unit must be 'kg'"),
        (lambda d: d["parameters"]["body_mass"].update(value=-1.5), "body_mass", "outside"),
        (lambda d: d["parameters"]["gravity"].update(value="heavy"), "gravity", "not a number"),
        (lambda d: d["parameters"]["gravity"].update(provenance="guess"), "gravity", "provenance"),
        (
            lambda d: d["parameters"].update(wing_area={"value": 1, "unit": "m^2", "provenance": "assumed"}),
            "wing_area",
            "unknown parameter",
        ),
        (lambda d: d.update(schema="other/1"), "schema", "must be"),
        (
            lambda d: d["parameters"]["friction_static"].update(value=0.5),
            "friction_static",
            "friction_kinetic",
        ),
    ],
)
def test_bad_file_names_the_field(tmp_path, edit, field, words):
    doc = _doc()
    edit(doc)
    with pytest.raises(ParameterError) as err:
        _load(tmp_path, doc)
    assert err.value.field == field
    assert words in str(err.value)
    assert "p.yaml" in str(err.value)


def test_unknown_effect_is_named(tmp_path):
    doc = _doc()
    doc["effects"].append("wind_gusts")
    with pytest.raises(EffectError, match="wind_gusts"):
        _load(tmp_path, doc)


def test_conflicting_effects_are_refused():
    with pytest.raises(EffectError, match="alternatives"):
        Model.default().with_effects("regularised_friction")
    with pytest.raises(EffectError, match="rigid_gear"):
        Model.default().with_effects("rigid_gear")


def test_broken_yaml_and_missing_file(tmp_path):
    with pytest.raises(ParameterError, match="not valid YAML"):
        _load(tmp_path, "parameters: [unclosed")
    with pytest.raises(ParameterError, match="cannot read"):
        ModelParams.load(tmp_path / "nope.yaml")


def test_a_note_with_a_comma_in_a_flow_mapping_names_the_quoting(tmp_path):
    """``{value: 0.8, note: measured, not guessed}``: YAML reads ``not guessed`` as a key of its
    own. The error says to quote the note, not only "unknown key"."""
    from slopelander.model.parameters import SCHEMA

    text = f"schema: {SCHEMA}\nparameters:\n  friction_kinetic: {{value: 0.8, note: measured, not guessed}}\n"
    with pytest.raises(ParameterError, match=r"must be quoted: note: \"a, b\""):
        _load(tmp_path, text)


def test_unknown_parameter_by_name():
    with pytest.raises(ParameterError, match="unknown parameter"):
        ModelParams.default().with_values(flux_capacitance=1.0)
