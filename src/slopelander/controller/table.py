"""The preset lookup table the companion flies with: load, validate, look up.

The file is written by ``slopelander table`` (schema in ``docs/lookup-table.md``). Loading it
checks everything a wrong file could get wrong and names the file and the field; looking up a
(slope, impact speed) never extrapolates:

* inside the grid, the four surrounding cells are examined. If every one of them predicts an
  *acceptable* outcome (ideal or under-used: landed without reaching the end of travel) the
  torques and leg angles are interpolated bilinearly between them: the presets vary smoothly
  there and any blend stays within what the cells hold;
* otherwise the request is near an envelope edge, where blending two presets may give one
  that neither cell was checked with; the preset of the *safe neighbour* is taken as it is:
  the surrounding cell with the best margin (ties: the landed one, then the nearest);
* outside the grid's range, :class:`OutOfTableRange` is raised, naming the axis and range.

Only numpy, pyyaml and the standard library are imported here: this runs on the vehicle.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from slopelander.errors import SlopelanderError

SCHEMA = "slopelander.lookup-table/1"
# Shipped with the package: `slopelander table --slope-step 5 --speed-step 0.25` (its generator
# field records the exact command); the companion flies with it unless given another table.
DEFAULT_TABLE = Path(__file__).with_name("default_table.yaml")
SCHEMA_NAME, SCHEMA_VERSION = SCHEMA.rsplit("/", 1)

OUTCOMES: tuple[str, ...] = (
    "ideal",
    "under_used",
    "end_of_travel",
    "slid",
    "joint_touch",
    "flip",
    "damaged",
)
"""Outcome names, best first (the model's Outcome classes, lower-cased)."""
LANDED = frozenset(OUTCOMES[:3])
ACCEPTABLE = frozenset(OUTCOMES[:2])
"""Outcomes between which presets may be interpolated."""

PRESET_FIELDS = ("tau_up", "tau_down", "angle_up_deg", "angle_down_deg")
REQUIRED_CELLS = (*PRESET_FIELDS, "outcome", "margin")
TORQUE_LIMITS = (0.0, 10.0)
ANGLE_LIMITS = (0.0, 89.0)


class TableError(SlopelanderError, ValueError):
    """A lookup-table file that cannot be used; names the file and the field."""

    def __init__(self, path: str | Path | None, field: str, why: str) -> None:
        where = f"{path}: " if path else ""
        super().__init__(f"{where}lookup table field '{field}': {why}")
        self.path = str(path) if path else None
        self.field = field


class OutOfTableRange(SlopelanderError, ValueError):  # noqa: N818 - the name the brief gives
    """A lookup outside the table's grid: the table does not extrapolate."""

    def __init__(self, axis: str, value: float, low: float, high: float) -> None:
        unit = "deg" if axis == "slope_deg" else "m/s"
        super().__init__(
            f"{axis} = {value:g} is outside the table's range {low:g}..{high:g} {unit}; "
            "the table does not extrapolate"
        )
        self.axis = axis
        self.value = value
        self.low = low
        self.high = high


@dataclass(frozen=True)
class Preset:
    """What to set on the legs for one landing, and what the model predicts for it.

    ``cell`` is the (slope index, speed index) the values came from (the nearest grid cell
    when they were interpolated); ``margin`` is the table's margin (0..1, see the docs).
    """

    tau_up: float
    tau_down: float
    angle_up_deg: float
    angle_down_deg: float
    outcome: str
    margin: float
    cell: tuple[int, int]
    interpolated: bool

    @property
    def landed(self) -> bool:
        return self.outcome in LANDED


class LookupTable:
    """A validated preset table on a (slope_deg, speed) grid."""

    def __init__(self, doc: dict[str, Any], path: str | Path | None = None) -> None:
        self.path = str(path) if path else None
        self.doc = doc
        self.slopes, self.speeds, self.cells = _validate(doc, self.path)
        self._rank = np.vectorize(OUTCOMES.index)(self.cells["outcome"])

    @classmethod
    def load(cls, path: str | Path) -> LookupTable:
        path = Path(path)
        try:
            text = path.read_text()
        except OSError as exc:
            raise TableError(path, "<file>", f"cannot read: {exc.strerror}") from None
        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
        try:
            doc = yaml.load(text, Loader=loader)
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f"line {mark.line + 1}" if mark else "unknown line"
            raise TableError(path, "<file>", f"not valid YAML ({where})") from None
        return cls(doc, path)

    # -- what the table holds ---------------------------------------------------------------
    @property
    def slope_range(self) -> tuple[float, float]:
        return float(self.slopes[0]), float(self.slopes[-1])

    @property
    def speed_range(self) -> tuple[float, float]:
        return float(self.speeds[0]), float(self.speeds[-1])

    @property
    def model(self) -> dict[str, Any]:
        """The model parameters and effects the table was computed with."""
        return self.doc["model"]

    @property
    def strategy(self) -> dict[str, Any]:
        return self.doc.get("strategy", {})

    def cell(self, i: int, j: int) -> Preset:
        c = self.cells
        return Preset(
            float(c["tau_up"][i, j]),
            float(c["tau_down"][i, j]),
            float(c["angle_up_deg"][i, j]),
            float(c["angle_down_deg"][i, j]),
            str(c["outcome"][i, j]),
            float(c["margin"][i, j]),
            (int(i), int(j)),
            False,
        )

    # -- lookup -------------------------------------------------------------------------------
    def lookup(self, slope_deg: float, speed: float) -> Preset:
        """The preset for a landing at ``slope_deg`` and vertical impact ``speed`` (m/s, down)."""
        i0, i1, fi = _bracket("slope_deg", self.slopes, slope_deg)
        j0, j1, fj = _bracket("speed", self.speeds, speed)
        corners = sorted({(i0, j0), (i0, j1), (i1, j0), (i1, j1)})
        nearest = (i1 if fi >= 0.5 else i0, j1 if fj >= 0.5 else j0)
        if all(self.cells["outcome"][c] in ACCEPTABLE for c in corners):
            w = {
                (i0, j0): (1 - fi) * (1 - fj),
                (i0, j1): (1 - fi) * fj,
                (i1, j0): fi * (1 - fj),
                (i1, j1): fi * fj,
            }
            vals = {}
            for name in PRESET_FIELDS:
                a = self.cells[name]
                v = (
                    w[(i0, j0)] * a[i0, j0]
                    + w[(i0, j1)] * a[i0, j1]
                    + w[(i1, j0)] * a[i1, j0]
                    + w[(i1, j1)] * a[i1, j1]
                )
                lo = min(a[c] for c in corners)
                hi = max(a[c] for c in corners)
                vals[name] = float(min(max(v, lo), hi))  # rounding must not leave the cells' span
            worst = max(corners, key=lambda c: self._rank[c])
            return Preset(
                **vals,
                outcome=str(self.cells["outcome"][worst]),
                margin=float(min(self.cells["margin"][c] for c in corners)),
                cell=nearest,
                interpolated=len(corners) > 1,
            )

        def key(c: tuple[int, int]) -> tuple[float, int, float]:
            di = (c[0] - i0 - fi) if i1 != i0 else 0.0
            dj = (c[1] - j0 - fj) if j1 != j0 else 0.0
            return (-float(self.cells["margin"][c]), int(self._rank[c] > 2), di * di + dj * dj)

        return self.cell(*min(corners, key=key))


def _bracket(axis: str, grid: np.ndarray, value: float) -> tuple[int, int, float]:
    """Indices of the grid points around ``value`` and its fraction between them."""
    v = float(value)
    lo, hi = float(grid[0]), float(grid[-1])
    if not (math.isfinite(v) and lo <= v <= hi):
        raise OutOfTableRange(axis, v, lo, hi)
    i1 = int(np.searchsorted(grid, v, side="left"))
    if grid[i1] == v:
        return i1, i1, 0.0
    i0 = i1 - 1
    return i0, i1, (v - float(grid[i0])) / (float(grid[i1]) - float(grid[i0]))


# -- validation -------------------------------------------------------------------------------
Fail = Callable[[str, str], TableError]
"""Builds the error naming the table's file, from the field and the reason."""


def _check_schema(doc: dict[str, Any], fail: Fail) -> None:
    """The schema names a lookup table, of the version this loader reads."""
    schema = doc.get("schema")
    if not isinstance(schema, str) or "/" not in schema:
        raise fail("schema", f"missing or malformed (expected '{SCHEMA}')")
    name, version = schema.rsplit("/", 1)
    if name != SCHEMA_NAME:
        raise fail("schema", f"'{schema}' is not a lookup table (expected '{SCHEMA}')")
    if version != SCHEMA_VERSION:
        raise fail("schema", f"version {version} is not supported (this loader reads {SCHEMA_VERSION})")


def _model_parameters(doc: dict[str, Any], fail: Fail) -> dict[str, Any]:
    """The parameters of the model that made the table (its effects must be listed too)."""
    model = doc.get("model")
    if not isinstance(model, dict):
        raise fail("model", "missing: a table must say which model produced it")
    if not isinstance(model.get("parameters"), dict) or not model["parameters"]:
        raise fail("model.parameters", "missing or empty")
    if not isinstance(model.get("effects"), list):
        raise fail("model.effects", "missing or not a list")
    return model["parameters"]


def _grid(doc: dict[str, Any], fail: Fail) -> tuple[np.ndarray, np.ndarray]:
    """The slope (deg) and speed (m/s) axes: each at least two numbers, strictly increasing."""
    axes = doc.get("axes")
    if not isinstance(axes, dict):
        raise fail("axes", "missing (needs slope_deg and speed)")
    grids = []
    for ax in ("slope_deg", "speed"):
        g = _float_array(axes.get(ax), f"axes.{ax}", fail)
        if g.ndim != 1 or g.size < 2:
            raise fail(f"axes.{ax}", "must be a list of at least two numbers")
        if not np.all(np.diff(g) > 0):
            k = int(np.flatnonzero(np.diff(g) <= 0)[0])
            raise fail(f"axes.{ax}", f"must increase strictly (entry {k + 1} = {g[k + 1]:g} after {g[k]:g})")
        grids.append(g)
    return grids[0], grids[1]


def _cell_arrays(doc: dict[str, Any], shape: tuple[int, int], fail: Fail) -> dict[str, np.ndarray]:
    """Every required cell field, one value per (slope, speed); outcomes by their known names."""
    cells_doc = doc.get("cells")
    if not isinstance(cells_doc, dict):
        raise fail("cells", "missing")
    cells: dict[str, np.ndarray] = {}
    for f in REQUIRED_CELLS:
        if f not in cells_doc:
            raise fail(f"cells.{f}", "missing")
        if f == "outcome":
            if isinstance(cells_doc[f], list) and cells_doc[f]:
                _check_rows(cells_doc[f], f"cells.{f}", fail, numbers=False)
            a = np.asarray(cells_doc[f], dtype=object)
        else:
            a = _float_array(cells_doc[f], f"cells.{f}", fail)
        if a.shape != shape:
            raise fail(
                f"cells.{f}",
                f"must be {shape[0]} rows (slopes) of {shape[1]} values (speeds), got shape {a.shape}",
            )
        cells[f] = a
    bad = [v for v in cells["outcome"].ravel() if v not in OUTCOMES]
    if bad:
        raise fail("cells.outcome", f"unknown outcome {bad[0]!r}; known: {', '.join(OUTCOMES)}")
    cells["outcome"] = cells["outcome"].astype(str)
    return cells


def _check_cell_limits(
    cells: dict[str, np.ndarray],
    grid: tuple[np.ndarray, np.ndarray],
    parameters: dict[str, Any],
    fail: Fail,
) -> None:
    """Torques, leg angles (within the model's joint range) and margins each in range; the first
    cell outside is named by its slope and speed."""
    slopes, speeds = grid
    angle_limits = _angle_limits(parameters)
    limits = {
        "tau_up": TORQUE_LIMITS,
        "tau_down": TORQUE_LIMITS,
        "angle_up_deg": angle_limits,
        "angle_down_deg": angle_limits,
        "margin": (0.0, 1.0),
    }
    for f, (lo, hi) in limits.items():
        a = cells[f]
        out = (a < lo) | (a > hi)
        if out.any():
            i, j = np.argwhere(out)[0]
            raise fail(
                f"cells.{f}",
                f"{a[i, j]:g} at slope {slopes[i]:g} deg, speed {speeds[j]:g} m/s is outside {lo:g}..{hi:g}",
            )


def _validate(doc: Any, path: str | None) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Check a table document part by part: its grid and its cells, as arrays."""

    def fail(field: str, why: str) -> TableError:
        return TableError(path, field, why)

    if not isinstance(doc, dict):
        raise fail("<file>", "must be a YAML mapping")
    _check_schema(doc, fail)
    parameters = _model_parameters(doc, fail)
    slopes, speeds = _grid(doc, fail)
    cells = _cell_arrays(doc, (slopes.size, speeds.size), fail)
    _check_cell_limits(cells, (slopes, speeds), parameters, fail)
    return slopes, speeds, cells


def _float_array(v: Any, field: str, fail) -> np.ndarray:
    if isinstance(v, list) and v and any(isinstance(row, list) for row in v):
        _check_rows(v, field, fail)
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise fail(field, "must hold numbers only") from None
    if a.dtype == object or a.ndim == 0:
        raise fail(field, "must be a list of numbers")
    if not np.isfinite(a).all():
        raise fail(field, "holds a non-finite number")
    return a


def _check_rows(rows: list, field: str, fail, *, numbers: bool = True) -> None:
    """Name the first row (counting from 1, one per slope) that is ragged or holds a non-number."""
    for n, row in enumerate(rows, 1):
        if not isinstance(row, list):
            raise fail(field, f"row {n} is {row!r}, not a list of numbers")
        for k, x in enumerate(row if numbers else (), 1):
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                raise fail(field, f"row {n}, value {k} is {x!r}, not a number")
    width = len(rows[0])
    for n, row in enumerate(rows, 1):
        if len(row) != width:
            raise fail(
                field,
                f"row {n} has {len(row)} values where row 1 has {width} "
                "(every row holds one value per speed)",
            )


def _angle_limits(parameters: dict[str, Any]) -> tuple[float, float]:
    """The joint's range from the table's own model parameters, else a generous default."""
    try:
        qmax = float(parameters["leg_angle_max_deg"]["value"])
        travel = float(parameters["leg_travel_deg"]["value"])
    except (KeyError, TypeError, ValueError):
        return ANGLE_LIMITS
    return qmax - travel, qmax
