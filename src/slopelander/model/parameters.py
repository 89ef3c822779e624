"""Model parameters: every number the physics uses, with its unit, bounds and provenance.

A parameter file is YAML (``default_parameters.yaml`` is the shipped one)::

    schema: slopelander.model-parameters/1
    parameters:
      body_mass: {value: 1.502, unit: kg, provenance: paper, note: Table II}
    effects: [leg_flex, end_of_travel, ...]

An override file holds only what it changes: every parameter it leaves out, and the effects
if it has no ``effects`` list, come from the shipped defaults. An entry needs a ``value``
(or is a bare number); ``unit`` is checked when given; ``provenance`` defaults to ``assumed``.
``slopelander params --out FILE`` writes the defaults, commented, to start from.

Parameters are addressable by name (``params.with_values(ground_damping=400)``) because the
identification tools fit them by name; the integrator sees them as one float array in
:data:`PARAMETER_NAMES` order.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from slopelander.errors import SlopelanderError

SCHEMA = "slopelander.model-parameters/1"
PROVENANCES = ("paper", "derived", "assumed", "identified")


class ParameterError(SlopelanderError, ValueError):
    """A parameter file or value is wrong; names the file (if any) and the field."""

    def __init__(self, field: str, why: str, source: str | None = None) -> None:
        where = f"{source}: " if source else ""
        super().__init__(f"{where}parameter '{field}': {why}")
        self.field = field
        self.source = source


@dataclass(frozen=True)
class ParameterSpec:
    name: str
    unit: str
    low: float
    high: float
    description: str


def _spec(name: str, unit: str, low: float, high: float, description: str) -> ParameterSpec:
    return ParameterSpec(name, unit, low, high, description)


INF = math.inf
# Order matters: it is the integrator's array layout (kernel.P_* indices follow it).
SPECS: tuple[ParameterSpec, ...] = (
    _spec("gravity", "m/s^2", 0.0, 30.0, "gravitational acceleration"),
    _spec("body_mass", "kg", 1e-3, 100.0, "body B: frame, battery, electronics, motors"),
    _spec("body_inertia", "kg*m^2", 1e-6, 10.0, "body B pitch inertia about its centre of mass"),
    _spec("rotor_arm", "m", 0.0, 2.0, "planar rotor position: distance from the centre along body x"),
    _spec("joint_x", "m", 0.0, 1.0, "leg joint distance from the centre along body x"),
    _spec("joint_z", "m", -0.5, 0.5, "leg joint distance below the centre of mass"),
    _spec("leg_mass", "kg", 1e-5, 10.0, "one planar leg (stands for a real pair)"),
    _spec("leg_inertia", "kg*m^2", 1e-9, 1.0, "planar leg inertia about its own centre of mass"),
    _spec("leg_length", "m", 0.01, 2.0, "joint to foot"),
    _spec("leg_angle_max_deg", "deg", 0.0, 89.0, "fully extended leg angle below the body plane"),
    _spec("leg_travel_deg", "deg", 1.0, 89.0, "joint travel from full extension to end of travel"),
    _spec("joints_per_planar_leg", "1", 1.0, 4.0, "real joints a planar leg stands for"),
    _spec("flex_stiffness", "N*m/rad", 1e-3, 1e5, "k_q: bending of one real leg, in series with its joint"),
    _spec("flex_damping", "N*m*s/rad", 1e-6, 1e3, "b_q: damping of one real leg's bending"),
    _spec("eot_zone_deg", "deg", 0.0, 20.0, "end-of-travel spring-damper acts within this of the limit"),
    _spec("eot_stiffness", "N*m/rad", 0.0, 1e5, "end-of-travel spring"),
    _spec("eot_damping", "N*m*s/rad", 0.0, 1e3, "end-of-travel damper"),
    _spec("factor_tau", "1/N", 0.0, 1.0, "downhill joint torque growth per newton of foot friction (eq. 3)"),
    _spec("factor_mu", "s/m", 0.0, 10.0, "downhill foot friction growth per m/s downhill (eq. 4)"),
    _spec("ground_stiffness", "N/m", 1.0, 1e8, "k_g: contact normal spring"),
    _spec("ground_damping", "N*s/m", 0.0, 1e6, "b_g: contact normal damper"),
    _spec("friction_kinetic", "1", 0.0, 5.0, "mu_k: sliding friction of a foot"),
    _spec("friction_static", "1", 0.0, 5.0, "mu_s: a stuck foot holds until |F_t| exceeds mu_s * N"),
    _spec("stiction_stiffness", "N/m", 1.0, 1e8, "tangential spring of a stuck foot"),
    _spec("stiction_damping", "N*s/m", 0.0, 1e6, "tangential damper of a stuck foot"),
    _spec("friction_smoothing_speed", "m/s", 1e-6, 1.0, "slip speed scale of the regularised law"),
    _spec("rotor_thrust_max", "N", 0.0, 500.0, "full forward thrust of one planar rotor (a real pair)"),
    _spec("rotor_reverse_ratio", "1", 0.0, 1.0, "full reverse thrust as a fraction of full forward"),
    _spec("rotor_time_constant", "s", 1e-3, 2.0, "first-order rotor speed response"),
    _spec("rotor_reversal_delay", "s", 0.0, 2.0, "stop-and-restart dead time when a rotor changes direction"),
    _spec("stribeck_speed", "m/s", 1e-5, 1.0, "v_s: slip speed scale of the fall to mu_k"),
    _spec("stribeck_exponent", "1", 0.5, 4.0, "mu_k + (mu_s - mu_k) exp(-(v / v_s)^delta)"),
    _spec(
        "rigid_contact_stiffness",
        "N/m",
        1.0,
        1e8,
        "normal spring of a stock rigid-gear foot (skid) on the ground",
    ),
    _spec(
        "rigid_contact_damping",
        "N*s/m",
        0.0,
        1e6,
        "normal damper of a stock rigid-gear foot (skid) on the ground",
    ),
    _spec(
        "rigid_load_limit",
        "N",
        1.0,
        1e5,
        "peak normal load on a rigid-gear foot (a real pair) beyond which the gear is damaged",
    ),
)
PARAMETER_NAMES: tuple[str, ...] = tuple(s.name for s in SPECS)
SPEC_BY_NAME = {s.name: s for s in SPECS}

_UNIT_ALIASES = {"·": "*", " ": "", "²": "^2", "⁻¹": "^-1"}


def _norm_unit(unit: str) -> str:
    return _norm_unit_text(str(unit))


@functools.lru_cache(maxsize=512)
def _norm_unit_text(u: str) -> str:
    """A unit written the canonical way; cached because a fit checks 35 units per candidate set."""
    for a, b in _UNIT_ALIASES.items():
        u = u.replace(a, b)
    return u


@dataclass(frozen=True)
class Parameter:
    value: float
    unit: str
    provenance: str
    note: str = ""


@dataclass(frozen=True)
class ModelParams:
    """A complete, validated parameter set plus the effects it was written for."""

    values: dict[str, Parameter]
    effects: tuple[str, ...]
    source: str | None = None
    _array: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in PARAMETER_NAMES:
            if name not in self.values:
                raise ParameterError(name, "missing", self.source)
        for name, p in self.values.items():
            _check_value(name, p, self.source)
        if self.values["friction_static"].value < self.values["friction_kinetic"].value:
            raise ParameterError("friction_static", "must not be below friction_kinetic", self.source)
        if self.values["leg_travel_deg"].value > self.values["leg_angle_max_deg"].value:
            raise ParameterError("leg_travel_deg", "exceeds leg_angle_max_deg", self.source)
        arr = np.array([self.values[n].value for n in PARAMETER_NAMES], dtype=np.float64)
        arr.setflags(write=False)
        object.__setattr__(self, "_array", arr)

    # -- access ---------------------------------------------------------------
    def __getitem__(self, name: str) -> float:
        try:
            return self.values[name].value
        except KeyError:
            raise ParameterError(name, "unknown parameter") from None

    def as_array(self) -> np.ndarray:
        return self._array

    @property
    def angle_max_deg(self) -> float:
        return self["leg_angle_max_deg"]

    @property
    def angle_min_deg(self) -> float:
        """The end-of-travel limit (full compression)."""
        return self["leg_angle_max_deg"] - self["leg_travel_deg"]

    def with_values(self, provenance: str = "identified", **changes: float) -> ModelParams:
        """A copy with some values replaced (by name), e.g. a fitted set."""
        values = dict(self.values)
        for name, v in changes.items():
            if name not in SPEC_BY_NAME:
                raise ParameterError(name, "unknown parameter")
            old = values[name]
            values[name] = Parameter(float(v), old.unit, provenance, old.note)
        return ModelParams(values, self.effects, self.source)

    # -- files ----------------------------------------------------------------
    @classmethod
    def default(cls) -> ModelParams:
        text = resources.files("slopelander.model").joinpath("default_parameters.yaml").read_text()
        return cls.from_yaml_text(text, source="default_parameters.yaml")

    @classmethod
    def load(cls, path: str | Path) -> ModelParams:
        path = Path(path)
        try:
            text = path.read_text()
        except OSError as exc:
            raise ParameterError("<file>", f"cannot read: {exc.strerror}", str(path)) from None
        return cls.from_yaml_text(text, source=str(path))

    @classmethod
    def from_yaml_text(cls, text: str, source: str | None = None) -> ModelParams:
        try:
            doc = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f"line {mark.line + 1}" if mark else "unknown line"
            raise ParameterError("<file>", f"not valid YAML ({where})", source) from None
        return cls.from_dict(doc, source)

    @classmethod
    def from_dict(cls, doc: Any, source: str | None = None) -> ModelParams:
        from slopelander.model.effects import check_effect_names

        if not isinstance(doc, dict):
            raise ParameterError("<file>", "must be a mapping with 'parameters'", source)
        if doc.get("schema") != SCHEMA:
            raise ParameterError("schema", f"must be '{SCHEMA}', got {doc.get('schema')!r}", source)
        raw = doc.get("parameters")
        if not isinstance(raw, dict):
            raise ParameterError("parameters", "missing or not a mapping", source)
        values: dict[str, Parameter] = {}
        for name, entry in raw.items():
            if name not in SPEC_BY_NAME:
                raise ParameterError(str(name), "unknown parameter", source)
            if isinstance(entry, (int, float)) and not isinstance(entry, bool):
                entry = {"value": entry}
            if not isinstance(entry, dict):
                raise ParameterError(name, "must be a number or a mapping with a value", source)
            if "value" not in entry:
                raise ParameterError(name, "missing 'value'", source)
            extra = sorted(str(k) for k in entry if k not in ("value", "unit", "provenance", "note"))
            if extra:
                why = f"unknown key(s) {extra}: value, unit, provenance, note"
                if all(entry[k] is None for k in entry if k not in ("value", "unit", "provenance", "note")):
                    # `{value: 1, note: a, b}`: YAML read the text after the comma as keys of their own
                    why += ' (a note or unit with a comma inside { } must be quoted: note: "a, b")'
                raise ParameterError(name, why, source)
            try:
                value = float(entry["value"])
            except (TypeError, ValueError):
                raise ParameterError(name, f"value {entry['value']!r} is not a number", source) from None
            values[name] = Parameter(
                value,
                str(entry.get("unit", SPEC_BY_NAME[name].unit)),
                str(entry.get("provenance", "assumed")),
                str(entry.get("note", "")),
            )
        missing = [n for n in PARAMETER_NAMES if n not in values]
        defaults = cls.default() if missing or "effects" not in doc else None
        for name in missing:
            values[name] = defaults.values[name]  # type: ignore[union-attr]
        effects = doc["effects"] if "effects" in doc else list(defaults.effects)  # type: ignore[union-attr]
        if not isinstance(effects, list) or not all(isinstance(e, str) for e in effects):
            raise ParameterError("effects", "must be a list of effect names", source)
        check_effect_names(effects, source)
        return cls(values, tuple(effects), source)

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA,
            "parameters": {
                n: {
                    "value": self.values[n].value,
                    "unit": self.values[n].unit,
                    "provenance": self.values[n].provenance,
                    **({"note": self.values[n].note} if self.values[n].note else {}),
                }
                for n in PARAMETER_NAMES
            },
            "effects": list(self.effects),
        }

    def save(self, path: str | Path) -> None:
        Path(path).write_text(yaml.safe_dump(self.to_dict(), sort_keys=False, allow_unicode=True))


def _flow(v: Any) -> str:
    text = yaml.safe_dump(v, default_flow_style=True, width=10_000, allow_unicode=True, sort_keys=False)
    return text.strip()


def commented_yaml(params: ModelParams | None = None) -> str:
    """A parameter file with a comment per parameter (meaning, unit, allowed range): the file
    ``slopelander params --out`` writes to start an override from."""
    params = params or ModelParams.default()
    lines = [
        "# slopelander model parameters (schema slopelander.model-parameters/1).",
        f"# Written from: {params.source or 'a parameter set in memory'}.",
        "# To override: keep only the parameters you change (and 'effects' if you change them);",
        "# everything left out comes from the shipped defaults. Then pass the file with --params.",
        "# provenance: paper = Bass, Tunney, Lussier Desbiens (RA-L 2022), Table II / Sec. III-V;",
        "#             derived = computed from paper values (the note says how);",
        "#             assumed = a choice where the paper is silent; identified = fitted to drops.",
        f"schema: {SCHEMA}",
        "parameters:",
    ]
    d = params.to_dict()
    for spec in SPECS:
        lines.append(f"  # {spec.description}; {spec.unit}, allowed {spec.low:g}..{spec.high:g}")
        lines.append(f"  {spec.name}: {_flow(d['parameters'][spec.name])}")
    lines.append("# effects switched on (slopelander simulate --without NAME switches one off for a run)")
    lines.append("effects:")
    lines += [f"  - {e}" for e in params.effects]
    return "\n".join(lines) + "\n"


def _check_value(name: str, p: Parameter, source: str | None) -> None:
    spec = SPEC_BY_NAME.get(name)
    if spec is None:
        raise ParameterError(name, "unknown parameter", source)
    if _norm_unit(p.unit) != _norm_unit(spec.unit):
        raise ParameterError(name, f"unit must be '{spec.unit}', got '{p.unit}'", source)
    if p.provenance not in PROVENANCES:
        raise ParameterError(
            name, f"provenance must be one of {', '.join(PROVENANCES)}, got '{p.provenance}'", source
        )
    if not math.isfinite(p.value):
        raise ParameterError(name, "must be finite", source)
    if not spec.low <= p.value <= spec.high:
        raise ParameterError(
            name, f"{p.value} {spec.unit} is outside {spec.low}..{spec.high} ({spec.description})", source
        )
