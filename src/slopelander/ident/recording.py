"""Drop recordings on disk: one CSV of states plus one JSON of conditions per drop.

The format is documented in ``docs/recordings.md``. Loading is strict because a silently
dropped sample or a misread unit would show up later as "missing physics": every problem is
a :class:`RecordingError` naming the file, the line and the field.
"""

from __future__ import annotations

import csv
import json
import math
import reprlib
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from slopelander.errors import SlopelanderError
from slopelander.model import ConditionError, LandingConditions, Outcome

SCHEMA = "slopelander.drop/1"
STATES: tuple[str, ...] = ("x", "z", "pitch", "x_rate", "z_rate", "pitch_rate")
COLUMNS: tuple[str, ...] = ("time", *STATES)
SI_UNITS: dict[str, str] = {
    "time": "s",
    "x": "m",
    "z": "m",
    "pitch": "rad",
    "x_rate": "m/s",
    "z_rate": "m/s",
    "pitch_rate": "rad/s",
}
_LENGTH = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}
_ANGLE = {"rad": 1.0, "deg": math.pi / 180.0}
_TIME = {"s": 1.0, "ms": 1e-3}
# every accepted unit of each column, as a factor to SI
UNITS: dict[str, dict[str, float]] = {
    "time": _TIME,
    "x": _LENGTH,
    "z": _LENGTH,
    "pitch": _ANGLE,
    "x_rate": {f"{u}/s": f for u, f in _LENGTH.items()},
    "z_rate": {f"{u}/s": f for u, f in _LENGTH.items()},
    "pitch_rate": {f"{u}/s": f for u, f in _ANGLE.items()},
}
OUTCOME_NAMES = {o.name.lower(): o for o in Outcome}


class RecordingError(SlopelanderError, ValueError):
    """A recording that cannot be read as written; says where (file, line, field)."""

    def __init__(self, path: str | Path, line: int | None, fieldname: str, why: str) -> None:
        where = f"{path}" + (f", line {line}" if line is not None else "")
        super().__init__(f"{where}, field '{fieldname}': {why}")
        self.path = str(path)
        self.line = line
        self.field = fieldname


@dataclass(frozen=True)
class Drop:
    """One recorded drop: sample times (s, 0 = first foot contact), the six states in SI
    units in the model's frame, the conditions at impact and where the data came from."""

    name: str
    t: np.ndarray
    states: np.ndarray
    conditions: LandingConditions
    outcome: Outcome | None = None
    source: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def rate_window(self) -> int | None:
        """Samples of the least-squares slope the recording's rates were differentiated with
        (``meta.rates``), or None when the rates were measured directly."""
        rates = self.meta.get("rates") if isinstance(self.meta, dict) else None
        if isinstance(rates, dict) and rates.get("method") == "lsq_slope":
            return int(rates.get("window", 3))
        return None

    @property
    def savgol(self) -> tuple[int, int, float] | None:
        """(window, polyorder, frame spacing in s) of the Savitzky-Golay filter the recording's
        rates were made with (``meta.rates``, an imported take), or None."""
        rates = self.meta.get("rates") if isinstance(self.meta, dict) else None
        if isinstance(rates, dict) and rates.get("method") == "savgol":
            return int(rates["window"]), int(rates["polyorder"]), float(rates["dt"])
        return None

    def __post_init__(self) -> None:
        if self.states.shape != (len(self.t), len(STATES)):
            raise ValueError(f"drop {self.name}: states must be ({len(self.t)}, 6), got {self.states.shape}")


# -- writing ------------------------------------------------------------------------------
def write_drop(drop: Drop, folder: str | Path) -> Path:
    """Write ``<name>.csv`` and ``<name>.json`` into ``folder``; returns the CSV path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    csv_path = folder / f"{drop.name}.csv"
    with csv_path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"{c} [{SI_UNITS[c]}]" for c in COLUMNS])
        for ti, row in zip(drop.t, drop.states, strict=True):
            w.writerow([f"{ti:.6f}", *(f"{v:.7g}" if math.isfinite(v) else "" for v in row)])
    meta = {
        "schema": SCHEMA,
        "conditions": drop.conditions.as_file_dict(),
        "outcome": drop.outcome.name.lower() if drop.outcome is not None else None,
        "source": drop.source,
        **({"meta": drop.meta} if drop.meta else {}),
    }
    (folder / f"{drop.name}.json").write_text(json.dumps(meta, indent=2) + "\n")
    return csv_path


def write_dataset(drops: list[Drop], folder: str | Path) -> Path:
    folder = Path(folder)
    for d in drops:
        write_drop(d, folder)
    return folder


# -- reading ------------------------------------------------------------------------------
def parse_header(cells: list[str], path: Path) -> tuple[list[str], np.ndarray]:
    """Column names in file order and each column's factor to SI, from ``name [unit]`` cells."""
    names: list[str] = []
    factors: list[float] = []
    for cell in cells:
        text = cell.strip()
        if "[" not in text or not text.endswith("]"):
            raise RecordingError(path, 1, text or "<empty>", "header cells must read 'name [unit]'")
        name, unit = text[:-1].split("[", 1)
        name, unit = name.strip(), unit.strip()
        if name not in UNITS:
            raise RecordingError(path, 1, name, f"unknown column; columns are {', '.join(COLUMNS)}")
        if unit not in UNITS[name]:
            raise RecordingError(path, 1, name, f"unknown unit '{unit}'; accepted: {', '.join(UNITS[name])}")
        if name in names:
            raise RecordingError(path, 1, name, "column appears twice")
        names.append(name)
        factors.append(UNITS[name][unit])
    missing = [c for c in COLUMNS if c not in names]
    if missing:
        raise RecordingError(path, 1, missing[0], "missing column")
    return names, np.array(factors)


def read_states(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Times and states (SI, file's frame) of one CSV; strict about every cell."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise RecordingError(path, None, "<file>", f"cannot read: {exc.strerror}") from None
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise RecordingError(path, 1, "<header>", "empty file")
    names, factors = parse_header(rows[0], path)
    data = []
    for lineno, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(names):
            raise RecordingError(
                path,
                lineno,
                names[min(len(row), len(names) - 1)],
                f"{len(row)} cells, the header has {len(names)}",
            )
        vals = []
        for name, cell in zip(names, row, strict=True):
            if not cell.strip() and name != "time":
                vals.append(math.nan)  # an empty cell: a gap, not seen (masked downstream)
                continue
            try:
                v = float(cell)
            except ValueError:
                raise RecordingError(path, lineno, name, f"'{cell.strip()}' is not a number") from None
            if not math.isfinite(v):
                raise RecordingError(
                    path, lineno, name, f"'{cell.strip()}' is not a finite number (a gap is an empty cell)"
                )
            vals.append(v)
        data.append((lineno, vals))
    if len(data) < 2:
        raise RecordingError(path, len(rows), "time", "fewer than two samples")
    arr = np.array([v for _, v in data]) * factors
    order = [names.index(c) for c in COLUMNS]
    arr = arr[:, order]
    t = arr[:, 0]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise RecordingError(
            path, data[i][0], "time", f"{t[i]:g} s does not follow {t[i - 1]:g} s (time must increase)"
        )
    return t, arr[:, 1:]


def _json_line(text: str, key: str) -> int | None:
    for i, line in enumerate(text.splitlines(), start=1):
        if f'"{key}"' in line:
            return i
    return None


def _read_json(path: Path) -> tuple[str, dict[str, Any]]:
    """The sidecar's text and its JSON object, of our schema."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise RecordingError(path, None, "<file>", f"cannot read: {exc.strerror}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RecordingError(path, exc.lineno, "<json>", f"not valid JSON: {exc.msg}") from None
    if not isinstance(doc, dict):
        raise RecordingError(path, 1, "<json>", "must be an object")
    if doc.get("schema") != SCHEMA:
        raise RecordingError(
            path, _json_line(text, "schema") or 1, "schema", f"must be '{SCHEMA}', got {doc.get('schema')!r}"
        )
    return text, doc


def _read_landing(path: Path, text: str, raw: object) -> LandingConditions:
    """The ``conditions`` object: known numeric conditions, slope and speed given, each in the
    model's range."""
    if not isinstance(raw, dict):
        raise RecordingError(path, _json_line(text, "conditions"), "conditions", "missing or not an object")
    known = {f.name for f in fields(LandingConditions)}
    for key, v in raw.items():
        if key not in known:
            raise RecordingError(
                path,
                _json_line(text, key),
                f"conditions.{key}",
                f"unknown condition; known: {', '.join(sorted(known))}",
            )
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise RecordingError(path, _json_line(text, key), f"conditions.{key}", f"{v!r} is not a number")
        if isinstance(v, int) and not -1e308 < v < 1e308:
            raise RecordingError(
                path, _json_line(text, key), f"conditions.{key}", f"{reprlib.repr(v)} is beyond any float"
            )
    for key in ("slope_deg", "speed"):
        if key not in raw:
            raise RecordingError(path, _json_line(text, "conditions"), f"conditions.{key}", "missing")
    cond = LandingConditions(**{k: float(v) for k, v in raw.items()})
    try:
        cond.validate(0.0, 37.5)
    except ConditionError as exc:
        why = str(exc).split(": ", 1)[-1]
        raise RecordingError(path, _json_line(text, exc.field), f"conditions.{exc.field}", why) from None
    return cond


def _read_outcome(path: Path, text: str, outcome: object) -> Outcome | None:
    """The observed outcome by its lower-case name, or None when the drop has none."""
    if outcome is None:
        return None
    if not isinstance(outcome, str) or outcome not in OUTCOME_NAMES:
        raise RecordingError(
            path,
            _json_line(text, "outcome"),
            "outcome",
            f"unknown outcome {outcome!r}; known: {', '.join(OUTCOME_NAMES)}",
        )
    return OUTCOME_NAMES[outcome]


def _savgol_rates_ok(rates: dict[str, Any]) -> bool:
    """Whether Savitzky-Golay rates say a window, polynomial order and frame spacing that fit."""
    win, order, dt = rates.get("window"), rates.get("polyorder"), rates.get("dt")
    return bool(
        isinstance(win, int)
        and isinstance(order, int)
        and not isinstance(win, bool)
        and not isinstance(order, bool)
        and isinstance(dt, (int, float))
        and not isinstance(dt, bool)
        and win >= 3
        and win % 2
        and 1 <= order < win
        and 0 < dt < 1e308
    )


def _other_rates_ok(rates: object) -> bool:
    """Whether rates not from Savitzky-Golay are measured, or least-squares slopes over an odd window."""
    win = rates.get("window") if isinstance(rates, dict) else None
    return bool(
        isinstance(rates, dict)
        and rates.get("method") in ("lsq_slope", "measured")
        and (rates.get("method") == "measured" or (isinstance(win, int) and win >= 3 and win % 2))
    )


def _read_meta(path: Path, text: str, meta: object) -> dict[str, Any]:
    """The ``meta`` object (empty when absent); its ``rates`` say how the rate columns were made
    (load_drop checks the frames against them), so they are checked here."""
    meta = {} if meta is None else meta
    if not isinstance(meta, dict):
        raise RecordingError(path, _json_line(text, "meta"), "meta", "must be an object")
    rates = meta.get("rates")
    if isinstance(rates, dict) and rates.get("method") == "savgol":
        if not _savgol_rates_ok(rates):
            raise RecordingError(
                path,
                _json_line(text, "rates"),
                "meta.rates",
                '"savgol" needs "window" (odd, >= 3), "polyorder" (1..window-1) and "dt" (s, > 0)',
            )
    elif rates is not None and not _other_rates_ok(rates):
        raise RecordingError(
            path,
            _json_line(text, "rates"),
            "meta.rates",
            'must be {"method": "measured"} or {"method": "lsq_slope", "window": odd number >= 3}',
        )
    return meta


def _read_source(path: Path, text: str, source: object) -> str:
    """The free-text note of where the data came from ("" when absent)."""
    if source is None:
        return ""
    if not isinstance(source, str):
        raise RecordingError(
            path, _json_line(text, "source"), "source", f"must be text, got {reprlib.repr(source)}"
        )
    return source


def read_conditions(path: str | Path) -> tuple[LandingConditions, Outcome | None, str, dict[str, Any]]:
    """Conditions, observed outcome, source note and extra metadata of one JSON sidecar."""
    path = Path(path)
    text, doc = _read_json(path)
    cond = _read_landing(path, text, doc.get("conditions"))
    outcome = _read_outcome(path, text, doc.get("outcome"))
    meta = _read_meta(path, text, doc.get("meta"))
    return cond, outcome, _read_source(path, text, doc.get("source")), meta


def load_drop(csv_path: str | Path) -> Drop:
    """One drop from its CSV and the JSON of the same name beside it."""
    csv_path = Path(csv_path)
    side = csv_path.with_suffix(".json")
    if not side.is_file():
        raise RecordingError(
            side, None, "<file>", f"missing: every drop needs its conditions beside {csv_path.name}"
        )
    t, states = read_states(csv_path)
    cond, outcome, source, meta = read_conditions(side)
    rates = meta.get("rates")
    if isinstance(rates, dict) and rates.get("method") == "savgol":
        step = np.diff(t)
        worst = int(np.argmax(np.abs(step - rates["dt"])))
        if abs(step[worst] - rates["dt"]) > 2e-6:
            raise RecordingError(
                csv_path,
                worst + 3,
                "time",
                f"{t[worst + 1]:g} s is not one frame ({rates['dt']:g} s, meta.rates.dt) after "
                f"{t[worst]:g} s: Savitzky-Golay rates need every frame, gaps as empty cells",
            )
    if not np.isfinite(states[t >= 0]).any(axis=0).all():
        col = STATES[int(np.argmin(np.isfinite(states[t >= 0]).any(axis=0)))]
        raise RecordingError(csv_path, None, col, "no value after first contact (every cell is a gap)")
    return Drop(csv_path.stem, t, states, cond, outcome, source, meta)


def load_dataset(folder: str | Path) -> list[Drop]:
    """Every drop of a dataset folder, sorted by name."""
    folder = Path(folder)
    if folder.is_file():
        raise RecordingError(
            folder,
            None,
            "<folder>",
            "a file, not a dataset folder: fit, diagnose and steps read a folder of drop "
            "recordings (docs/recordings.md); a flight log's landings are compared "
            "(slopelander compare FILE), not identified (docs/flight-logs.md, known limits)",
        )
    if not folder.is_dir():
        raise RecordingError(folder, None, "<folder>", "no such dataset folder")
    csvs = sorted(folder.glob("*.csv"))
    if not csvs:
        raise RecordingError(folder, None, "<folder>", "holds no drop (*.csv)")
    return [load_drop(p) for p in csvs]


# -- converting ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Convention:
    """How a foreign recording is framed and signed, relative to this format.

    ``x_uphill``: its x grows uphill (ours grows downhill). ``pitch_nose_down``: its pitch
    is positive nose-down. ``slope_frame``: its x runs along the slope and z along the
    surface normal (ours: horizontal and vertical). ``time_offset``: seconds to add so that
    0 is the first foot contact. ``columns``: our column name -> its column name.
    """

    x_uphill: bool = False
    pitch_nose_down: bool = False
    slope_frame: bool = False
    time_offset: float = 0.0
    columns: dict[str, str] = field(default_factory=dict)


def convert(
    src_csv: str | Path,
    conditions: LandingConditions,
    folder: str | Path,
    convention: Convention,
    *,
    name: str | None = None,
    source: str = "",
    units: dict[str, str] | None = None,
) -> Path:
    """Rewrite a foreign CSV (its own column names, units in ``name [unit]`` headers or given
    in ``units``, its own frame and signs) as a drop of this format in ``folder``."""
    src_csv = Path(src_csv)
    rows = list(csv.reader(src_csv.read_text().splitlines()))
    if not rows:
        raise RecordingError(src_csv, 1, "<header>", "empty file")
    back = {v: k for k, v in convention.columns.items()}
    header = []
    for cell in rows[0]:
        text = cell.strip()
        base, unit = text[:-1].split("[", 1) if "[" in text and text.endswith("]") else (text, "")
        base, unit = base.strip(), unit.strip()
        ours = back.get(base, base)
        if units and ours in units:
            unit = units[ours]
        header.append(f"{ours} [{unit}]")
    tmp = Path(folder) / f".{src_csv.stem}.convert.csv"
    Path(folder).mkdir(parents=True, exist_ok=True)
    with tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows[1:])
    try:
        t, s = read_states(tmp)
    except RecordingError as exc:
        raise RecordingError(
            src_csv, exc.line, convention.columns.get(exc.field, exc.field), str(exc).split(": ", 1)[-1]
        ) from None
    finally:
        tmp.unlink(missing_ok=True)
    s = s.copy()
    if convention.x_uphill:
        s[:, [0, 3]] *= -1
    if convention.pitch_nose_down:
        s[:, [2, 5]] *= -1
    if convention.slope_frame:
        a = math.radians(conditions.slope_deg)
        c, sn = math.cos(a), math.sin(a)
        # downhill tangent (c, -sn) and normal (sn, c) of the surface, in our frame
        for i, j in ((0, 1), (3, 4)):
            xs, zs = s[:, i].copy(), s[:, j].copy()
            s[:, i] = c * xs + sn * zs
            s[:, j] = -sn * xs + c * zs
        s[:, 2] -= a  # level with the slope is pitch -slope in our frame
    drop = Drop(
        name or src_csv.stem,
        t + convention.time_offset,
        s,
        conditions,
        None,
        source or f"converted from {src_csv.name}",
    )
    return write_drop(drop, folder)
