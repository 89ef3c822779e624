"""The markers file: which markers are the body and the roof, and each take's conditions.

A small YAML (docs/import.md) read strictly: an unknown key, a length without its unit, a
condition the take measures itself (slope, impact speed and attitude) all stop the import with
the file and the field named, before any take is read.
"""

from __future__ import annotations

import csv
import math
import reprlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from slopelander.ident.mocap.take import MocapError

SCHEMA = "slopelander.markers/1"
_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
GIVEN = (
    "tau_up",
    "tau_down",
    "angle_up_deg",
    "angle_down_deg",
    "reverse_percent",
    "reverse_delay",
    "reverse_duration",
    "reverse_ramp",
)
"""Conditions a take cannot measure: the leg presets and the thrust profile."""
MEASURED = ("slope_deg", "speed", "horizontal_speed", "pitch_deg", "pitch_rate_dps")
"""Conditions every take measures itself (roof plane, free flight up to first contact)."""
OUTCOMES = ("ideal", "under_used", "end_of_travel", "slid", "joint_touch", "flip")
AXES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")


@dataclass(frozen=True)
class RigidBodySpec:
    """A rigid body the capture software solved (Motive): its name, where the centre of mass
    sits in its local frame (m), and which of its local axes are the vehicle's forward and up."""

    name: str
    centre_of_mass: np.ndarray
    forward: str
    up: str


@dataclass(frozen=True)
class MarkerSet:
    path: Path
    body: dict[str, np.ndarray]
    """Body-frame position of each cluster marker, m (x forward, y left, z up; origin = CoM)."""
    rigid_body: RigidBodySpec | None
    rigid_tolerance: float
    """m: how far a marker may stray from the cluster's declared shape."""
    roof: tuple[str, ...]
    roof_height: float
    """m: height of a roof marker's centre above the surface (its radius, on a flat base)."""
    plane: tuple[np.ndarray, np.ndarray] | None
    """(point m, unit normal) in the capture's axes, when the roof is given as a plane."""
    up_axis: str | None
    latency_s: float
    rate_window_s: float
    rate_polyorder: int
    lateral_limit: float
    yaw_limit_deg: float
    roll_limit_deg: float
    before_s: float
    after_s: float
    conditions: dict[str, float]
    takes: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Per take (file name or stem): its conditions and outcome, over ``conditions``."""
    takes_table: Path | None = None
    """The CSV the takes came from, if any (not a take itself)."""
    feet: tuple[str, ...] = ()
    """Markers on the feet: first contact is where the first of them reaches the roof."""
    foot_height: float = 0.0
    """m: height of a foot marker's centre above the roof when its foot touches."""

    def take_entry(self, path: Path) -> dict[str, Any]:
        """The conditions of the take in ``path`` (its own over the shared ones)."""
        entry = self.takes.get(path.name, self.takes.get(path.stem))
        if entry is None:  # the table names the take by another export of it (drop02.c3d, drop02.csv)
            same = [v for k, v in self.takes.items() if Path(k).stem == path.stem]
            entry = same[0] if len(same) == 1 else None
        if entry is None and self.takes:
            raise MocapError(self.path, path.stem, "takes", f"no entry for {path.name} in the takes table")
        merged: dict[str, Any] = dict(self.conditions)
        merged.update(entry or {})
        return merged


def _err(path: Path, fieldname: str, why: str) -> MocapError:
    return MocapError(path, None, fieldname, why)


def _number(path: Path, name: str, v: object, lo: float = -math.inf, hi: float = math.inf) -> float:
    try:
        x = math.nan if isinstance(v, bool) or not isinstance(v, (int, float)) else float(v)
    except OverflowError:  # an integer beyond any float
        x = math.nan
    if not math.isfinite(x):
        raise _err(path, name, f"{reprlib.repr(v)} is not a number")
    if not lo <= x <= hi:
        raise _err(path, name, f"{x:g} must lie within {lo:g}..{hi:g}")
    return x


def _whole(path: Path, name: str, v: object, lo: int, hi: int) -> int:
    """A whole number in lo..hi (a fraction is refused, not rounded)."""
    if _number(path, name, v, lo, hi) != int(v):  # type: ignore[call-overload]
        raise _err(path, name, f"{v!r} is not a whole number")
    return int(v)  # type: ignore[call-overload]


def _name(path: Path, name: str, v: object) -> str:
    """A marker's or rigid body's name: text or a number as YAML reads it, never a list or mapping."""
    if isinstance(v, bool) or not isinstance(v, (str, int, float)) or not str(v).strip():
        raise _err(path, name, f"{v!r} is not a name")
    return str(v).strip()


def _mapping(path: Path, name: str, v: object, what: str) -> dict:
    """A section that must be a mapping; ``what`` says what it holds."""
    if not isinstance(v, dict):
        raise _err(path, name, f"must be a mapping {what}, got {v!r}")
    return v


def _keys(path: Path, where: str, doc: dict, known: set[str]) -> None:
    for k in doc:
        if k not in known:
            raise _err(path, f"{where}{k}", f"unknown key; known: {', '.join(sorted(known))}")


def _axis(path: Path, name: str, v: object) -> str:
    text = str(v).strip().upper()
    if text in ("X", "Y", "Z"):
        text = "+" + text
    if text not in AXES:
        raise _err(path, name, f"{v!r} is not an axis; one of {', '.join(AXES)}")
    return text


def _vector(path: Path, name: str, v: object, scale: float) -> np.ndarray:
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise _err(path, name, f"{v!r} is not [x, y, z]")
    return np.array([_number(path, f"{name}[{i}]", c) for i, c in enumerate(v)]) * scale


def _conditions(path: Path, where: str, doc: object) -> dict[str, Any]:
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise _err(path, where, f"must be a mapping of condition: value, got {doc!r}")
    out: dict[str, Any] = {}
    for k, v in doc.items():
        if k in MEASURED:
            raise _err(path, f"{where}.{k}", "measured from the take (roof plane, free flight): remove it")
        if k == "outcome":
            if v not in OUTCOMES:
                raise _err(path, f"{where}.outcome", f"{v!r}; one of {', '.join(OUTCOMES)}")
            out[k] = v
            continue
        if k not in GIVEN:
            raise _err(
                path, f"{where}.{k}", f"unknown condition; a take's given conditions are {', '.join(GIVEN)}"
            )
        out[k] = _number(path, f"{where}.{k}", v)
    return out


_TOP_KEYS = {
    "schema",
    "units",
    "body",
    "roof",
    "feet",
    "up_axis",
    "latency_s",
    "rates",
    "planarity",
    "keep",
    "conditions",
    "takes",
}


def _read_yaml(path: Path) -> dict:
    """The file's YAML mapping; a file that cannot be read or parsed is named with its line."""
    import yaml

    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise _err(path, "<file>", f"cannot read: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise _err(path, "<file>", f"not a text file (byte {exc.start}: {exc.reason})") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else "<yaml>"
        raise _err(path, where, f"not valid YAML: {getattr(exc, 'problem', exc)}") from None
    if not isinstance(doc, dict):
        raise _err(path, "<yaml>", "must be a mapping")
    return doc


def _length_scale(path: Path, doc: dict) -> float:
    """Metres per unit of the file's lengths, once the schema is known to be ours."""
    if doc.get("schema") != SCHEMA:
        raise _err(path, "schema", f"must be '{SCHEMA}', got {doc.get('schema')!r}")
    units = doc.get("units")
    if not isinstance(units, str) or units not in _UNITS:
        raise _err(
            path, "units", f"{units!r}: say the unit of this file's lengths, one of {', '.join(_UNITS)}"
        )
    return _UNITS[units]


def _rigid_body(path: Path, body_doc: dict, s: float) -> RigidBodySpec:
    """The rigid body the capture software solved, its centre of mass and its axes."""
    if "markers" in body_doc:
        raise _err(path, "body", "give either markers or rigid_body, not both")
    rigid = RigidBodySpec(
        _name(path, "body.rigid_body", body_doc["rigid_body"]),
        _vector(path, "body.centre_of_mass", body_doc.get("centre_of_mass", [0, 0, 0]), s),
        _axis(path, "body.forward", body_doc.get("forward", "+X")),
        _axis(path, "body.up", body_doc.get("up", "+Z")),
    )
    if rigid.forward.strip("+-") == rigid.up.strip("+-"):
        raise _err(path, "body.up", f"the same axis as body.forward ({rigid.forward})")
    return rigid


def _body_markers(path: Path, raw: object, s: float) -> dict[str, np.ndarray]:
    """The cluster's markers in the body frame (m): at least 3, not on one line, so that the
    pose can be found from them."""
    if not isinstance(raw, dict) or len(raw) < 3:
        raise _err(path, "body.markers", "need at least 3 markers: name: [x, y, z] in the body frame")
    body = {
        _name(path, "body.markers", name): _vector(path, f"body.markers.{name}", v, s)
        for name, v in raw.items()
    }
    pts = np.array(list(body.values()))
    sv = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    if sv[1] < 1e-3 * max(sv[0], 1e-12) or sv[0] < 1e-3:
        raise _err(path, "body.markers", "the markers lie on one line: their pose cannot be found")
    return body


def _body(path: Path, doc: dict, s: float) -> tuple[dict[str, np.ndarray], RigidBodySpec | None, float]:
    """The ``body`` section: the cluster's markers or the solved rigid body, and how far (m) a
    marker may stray from the cluster's shape."""
    body_doc = doc.get("body")
    if body_doc is None:
        raise _err(path, "body", "missing: name the body's markers (or its rigid body)")
    _mapping(path, "body", body_doc, "{markers: {name: [x, y, z]}} or {rigid_body: name}")
    _keys(
        path,
        "body.",
        body_doc,
        {"markers", "rigid_body", "centre_of_mass", "forward", "up", "rigid_tolerance"},
    )
    body: dict[str, np.ndarray] = {}
    rigid = None
    if "rigid_body" in body_doc:
        rigid = _rigid_body(path, body_doc, s)
    else:
        body = _body_markers(path, body_doc.get("markers"), s)
    tol = _number(path, "body.rigid_tolerance", body_doc.get("rigid_tolerance", 0.005 / s), 0.0) * s
    return body, rigid, tol


def _roof_plane(path: Path, p: object, s: float) -> tuple[np.ndarray, np.ndarray]:
    """A roof given as a plane: a point on it (m) and its unit normal, in the capture's axes."""
    if not isinstance(p, dict) or set(p) != {"point", "normal"}:
        raise _err(path, "roof.plane", "must be {point: [x, y, z], normal: [x, y, z]} in the capture's axes")
    n = _vector(path, "roof.plane.normal", p["normal"], 1.0)
    if np.linalg.norm(n) < 1e-9:
        raise _err(path, "roof.plane.normal", "is zero")
    return _vector(path, "roof.plane.point", p["point"], s), n / np.linalg.norm(n)


def _roof(
    path: Path, doc: dict, s: float
) -> tuple[tuple[str, ...], float, tuple[np.ndarray, np.ndarray] | None]:
    """The ``roof`` section: its markers (or its plane) and the markers' height above the surface (m)."""
    roof_doc = doc.get("roof")
    if roof_doc is None:
        raise _err(path, "roof", "missing: name the roof's markers (or give its plane)")
    _mapping(path, "roof", roof_doc, "{markers: [...]} or {plane: {point, normal}}")
    _keys(path, "roof.", roof_doc, {"markers", "plane", "marker_height"})
    roof_height = _number(path, "roof.marker_height", roof_doc.get("marker_height", 0.0), 0.0) * s
    if "markers" in roof_doc:
        raw = roof_doc["markers"]
        if not isinstance(raw, list) or len(raw) < 3:
            raise _err(path, "roof.markers", "need a list of at least 3 markers on the surface")
        return tuple(_name(path, f"roof.markers[{i}]", m) for i, m in enumerate(raw)), roof_height, None
    if "plane" in roof_doc:
        return (), roof_height, _roof_plane(path, roof_doc["plane"], s)
    raise _err(path, "roof", "give markers: [...] or plane: {point, normal}")


def _feet(path: Path, doc: dict, s: float, others: set[str]) -> tuple[tuple[str, ...], float]:
    """The optional ``feet`` section: the foot markers (none of the body's or roof's ``others``)
    and their height above the roof (m) when a foot touches."""
    feet_doc = doc.get("feet")
    if feet_doc is None:
        return (), 0.0
    if not isinstance(feet_doc, dict):
        raise _err(path, "feet", f"must be {{markers: [...], marker_height: h}}, got {feet_doc!r}")
    _keys(path, "feet.", feet_doc, {"markers", "marker_height"})
    raw = feet_doc.get("markers")
    if not isinstance(raw, list) or not raw:
        raise _err(path, "feet.markers", "need a list of the markers on the feet (one or more)")
    feet = tuple(_name(path, f"feet.markers[{i}]", m) for i, m in enumerate(raw))
    clash = [m for m in feet if m in others]
    if clash:
        raise _err(path, "feet.markers", f"{', '.join(clash)} is also a body or roof marker")
    if "marker_height" not in feet_doc:
        raise _err(
            path,
            "feet.marker_height",
            "missing: the height of a foot marker's centre above the roof when its foot touches",
        )
    return feet, _number(path, "feet.marker_height", feet_doc["marker_height"], 0.0) * s


def _section(path: Path, doc: dict, name: str, known: set[str]) -> dict:
    """An optional section of settings (empty when absent), refusing keys it does not know."""
    section = doc.get(name)
    if section is None:
        return {}
    _mapping(path, name, section, f"of {', '.join(sorted(known))}")
    _keys(path, f"{name}.", section, known)
    return section


def _takes(path: Path, doc: dict) -> tuple[dict[str, dict[str, Any]], Path | None]:
    """Each take's conditions, from the file itself or from the CSV table it names (returned too)."""
    takes_doc = doc.get("takes")
    if isinstance(takes_doc, str):
        table = path.parent / takes_doc
        return _takes_table(table), table
    if isinstance(takes_doc, dict):
        return {
            str(name): _conditions(path, f"takes.{name}", entry) for name, entry in takes_doc.items()
        }, None
    if takes_doc is not None:
        raise _err(
            path, "takes", f"a mapping take: {{conditions}} or the name of a CSV table, got {takes_doc!r}"
        )
    return {}, None


def load_markerset(path: str | Path) -> MarkerSet:
    """Read and check a markers file (docs/import.md)."""
    path = Path(path)
    doc = _read_yaml(path)
    _keys(path, "", doc, _TOP_KEYS)
    s = _length_scale(path, doc)
    body, rigid, tol = _body(path, doc, s)
    roof, roof_height, plane = _roof(path, doc, s)
    feet, foot_height = _feet(path, doc, s, set(body) | set(roof))
    up_axis = _axis(path, "up_axis", doc["up_axis"]) if "up_axis" in doc else None
    rates = _section(path, doc, "rates", {"window_s", "polyorder"})
    plan = _section(path, doc, "planarity", {"lateral", "yaw_deg", "roll_deg"})
    keep = _section(path, doc, "keep", {"before_s", "after_s"})
    takes, table = _takes(path, doc)
    return MarkerSet(
        path,
        body,
        rigid,
        tol,
        roof,
        roof_height,
        plane,
        up_axis,
        _number(path, "latency_s", doc.get("latency_s", 0.0), 0.0, 1.0),
        _number(path, "rates.window_s", rates.get("window_s", 0.03), 0.0, 1.0),
        _whole(path, "rates.polyorder", rates.get("polyorder", 2), 1, 5),
        _number(path, "planarity.lateral", plan.get("lateral", 0.02 / s), 0.0) * s,
        _number(path, "planarity.yaw_deg", plan.get("yaw_deg", 5.0), 0.0, 180.0),
        _number(path, "planarity.roll_deg", plan.get("roll_deg", 5.0), 0.0, 180.0),
        _number(path, "keep.before_s", keep.get("before_s", 0.1), 0.0, 10.0),
        _number(path, "keep.after_s", keep.get("after_s", 0.6), 0.05, 30.0),
        _conditions(path, "conditions", doc.get("conditions")),
        takes,
        table,
        feet,
        foot_height,
    )


def _takes_table(path: Path) -> dict[str, dict[str, Any]]:
    """A CSV of takes: a ``take`` column (file name) and one column per given condition."""
    try:
        rows = list(csv.reader(path.read_text().splitlines()))
    except OSError as exc:
        raise _err(path, "<file>", f"cannot read: {exc.strerror}") from None
    except (ValueError, csv.Error) as exc:  # a NUL in the name, bytes that are not text, a huge cell
        raise _err(path, "<file>", f"cannot read as a CSV table: {exc}") from None
    if not rows or not rows[0] or rows[0][0].strip() != "take":
        raise _err(path, "line 1", "the first column must be 'take' (the take's file name)")
    head = [c.strip() for c in rows[0]]
    out: dict[str, dict[str, Any]] = {}
    for lineno, row in enumerate(rows[1:], start=2):
        if not row or not any(c.strip() for c in row):
            continue
        if len(row) != len(head):
            raise _err(path, f"line {lineno}", f"{len(row)} cells, the header has {len(head)}")
        entry: dict[str, Any] = {}
        for name, cell in zip(head[1:], row[1:], strict=True):
            if name == "outcome":
                entry[name] = cell.strip()
                continue
            try:
                entry[name] = float(cell)
            except ValueError:
                raise _err(path, f"line {lineno}, {name}", f"'{cell.strip()}' is not a number") from None
        out[row[0].strip()] = _conditions(path, f"line {lineno}", entry)
    return out
