"""Readers of the motion-capture exports a lab hands over; each returns a :class:`Take`.

- C3D through the ``c3d`` package (pure Python, numpy only: it installs wherever pip does, reads
  the Intel, DEC and MIPS variants and writes C3D too); units from ``POINT:UNITS``, the rate from
  ``POINT:RATE``, the vertical axis from ``POINT:Y_SCREEN`` when the file has it.
- Vicon Nexus trajectory CSV (Nexus 2.x "Trajectories" section): rate on the line under the
  section name, units on the row under ``Frame,Sub Frame,X,Y,Z``.
- OptiTrack Motive CSV (format version 1.2x, Motive 2.x and 3.x): rate (``Export Frame Rate``)
  and ``Length Units`` from the first line; labelled markers and solved rigid bodies.
- Qualisys QTM TSV (3D export): rate from ``FREQUENCY``; the format is defined in millimetres.

Nothing is guessed: a file that does not say its rate or its units is refused; a vertical axis
the file does not declare is found from the free fall (docs/import.md). Gaps stay NaN.
"""

from __future__ import annotations

import csv
import math
import warnings
from pathlib import Path

import numpy as np

from slopelander.ident.mocap.take import MocapError, RigidBody, Take

LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
_MOTIVE_UNITS = {"meters": 1.0, "centimeters": 1e-2, "millimeters": 1e-3}
C3D_KEY = 0x50
"""Byte 2 of every C3D file (the header's key)."""


def read_take(path: str | Path) -> Take:
    """The take in ``path``, read by the reader its extension and first line call for."""
    path = Path(path)
    if not path.is_file():
        raise MocapError(path, None, "<file>", "no such file")
    suffix = path.suffix.lower()
    if suffix == ".c3d":
        return read_c3d(path)
    if suffix == ".tsv":
        return read_qualisys_tsv(path)
    if suffix == ".csv":
        first = _first_line(path)
        if first.split(",")[0].strip() in ("Trajectories", "Devices", "Model Outputs", "Joints", "Segments"):
            return read_vicon_csv(path)
        if first.startswith("Format Version"):
            return read_motive_csv(path)
        if first.startswith("time ["):
            raise MocapError(
                path,
                None,
                "<format>",
                "this is a drop recording already (docs/recordings.md), not a marker take",
            )
        raise MocapError(
            path,
            None,
            "<format>",
            f"a CSV from an exporter this reader does not know (first line {first[:40]!r}); expected "
            "Vicon Nexus ('Trajectories') or OptiTrack Motive ('Format Version,1.2x,...')",
        )
    raise MocapError(
        path, None, "<format>", f"unknown extension '{path.suffix}'; expected .c3d, .csv or .tsv"
    )


def _first_line(path: Path) -> str:
    try:
        with path.open("r", encoding="utf-8-sig", errors="replace") as fh:
            return fh.readline().strip()
    except OSError as exc:
        raise MocapError(path, None, "<file>", f"cannot read: {exc.strerror}") from None


def _rate(path: Path, take: str, fieldname: str, text: object) -> float:
    try:
        rate = float(str(text).strip())
    except ValueError:
        raise MocapError(path, take, fieldname, f"{text!r} is not a frame rate") from None
    if not (math.isfinite(rate) and 1.0 <= rate <= 100000.0):
        raise MocapError(path, take, fieldname, f"frame rate {rate:g} Hz makes no sense")
    return rate


# -- C3D ------------------------------------------------------------------------------------
def read_c3d(path: Path) -> Take:
    take = path.stem
    try:
        import c3d
    except ModuleNotFoundError:
        raise MocapError(
            path, take, "<reader>", "reading C3D needs the 'c3d' package: pip install 'slopelander[sim]'"
        ) from None
    try:
        head = path.read_bytes()[:512]
    except OSError as exc:
        raise MocapError(path, take, "<file>", f"cannot read: {exc.strerror}") from None
    if len(head) < 512 or head[1] != C3D_KEY:
        raise MocapError(
            path, take, "<header>", "not a C3D file (no C3D key 0x50 in the first 512-byte block)"
        )
    with path.open("rb") as fh, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            r = c3d.Reader(fh)
            units_param = r.get("POINT:UNITS")
            units = units_param.string_value.strip().lower() if units_param is not None else None
            rate = float(r.point_rate)
            labels = tuple(s.strip() for s in r.point_labels) if r.get("POINT:LABELS") is not None else ()
            screen = r.get_screen_axis()
            expected = int(r.frame_count)
            used = int(r.point_used)
            pts = [p[:, :4] for _, p, _ in r.read_frames(copy=True)]
        except MocapError:
            raise
        except Exception as exc:  # the reader's own errors on a damaged file: struct, value, index
            raise MocapError(
                path, take, "<header>", f"damaged C3D file ({type(exc).__name__}: {exc})"
            ) from None
    if units is None:
        raise MocapError(path, take, "POINT:UNITS", "missing: the file does not say its length unit")
    if units not in LENGTH_UNITS:
        raise MocapError(
            path, take, "POINT:UNITS", f"unknown unit '{units}'; accepted: {', '.join(LENGTH_UNITS)}"
        )
    rate = _rate(path, take, "POINT:RATE", rate)
    if len(labels) != used:
        raise MocapError(path, take, "POINT:LABELS", f"{len(labels)} labels for {used} markers")
    if len(pts) < expected:
        raise MocapError(
            path,
            take,
            "<data>",
            f"truncated: {len(pts)} of the {expected} frames the header announces are there",
        )
    if not pts:
        raise MocapError(path, take, "<data>", "no frames")
    arr = np.stack(pts).astype(np.float64)
    xyz = arr[:, :, :3] * LENGTH_UNITS[units]
    xyz[arr[:, :, 3] < 0] = np.nan  # the residual word's sign marks a point not seen
    up = None
    if screen is not None:
        up = str(screen[1]).strip().upper()
        if up not in ("+X", "-X", "+Y", "-Y", "+Z", "-Z"):
            raise MocapError(path, take, "POINT:Y_SCREEN", f"{up!r} is not an axis (+X, -Y, ...)")
    del caught
    return Take(
        path, take, "C3D", rate, labels, xyz, f"POINT:UNITS = '{units}'", up, "POINT:Y_SCREEN" if up else ""
    )


def write_c3d(
    path: Path, labels: list[str], xyz_m: np.ndarray, rate: float, *, up: str = "+Z", units: str = "mm"
) -> None:
    """A C3D file of marker positions (metres in, ``units`` in the file), NaN written as not
    seen, with ``POINT:Y_SCREEN`` naming the vertical axis (as Vicon and Qualisys export it)."""
    import c3d

    scale = 1.0 / LENGTH_UNITS[units]
    w = c3d.Writer(point_rate=float(rate), analog_rate=0.0, point_scale=-1.0, point_units=units.ljust(4))
    w.set_point_labels(labels)
    horiz = "+X" if up.strip("+-") != "X" else "+Y"
    w.set_screen_axis(X=horiz, Y=up)
    empty = np.zeros((0, 0))
    frames = []
    for f in range(xyz_m.shape[0]):
        p = np.zeros((len(labels), 5), dtype=np.float32)
        seen = np.isfinite(xyz_m[f]).all(axis=1)
        p[seen, :3] = xyz_m[f, seen] * scale
        p[~seen, 3] = -1.0
        p[seen, 4] = 3  # cameras bits: a marker seen is seen by some camera
        frames.append((p, empty))
    w.add_frames(frames)
    with path.open("wb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "no analog data": a take of markers only has none
        w.write(fh)


# -- Vicon Nexus CSV -------------------------------------------------------------------------
def _cell_float(text: str) -> float:
    text = text.strip()
    return float(text) if text else math.nan


def _numbers(path: Path, take: str, rows: list[tuple[int, list[str]]], names: list[str], width: int):
    out = np.full((len(rows), width), np.nan)
    for k, (lineno, row) in enumerate(rows):
        if len(row) > width:
            row = row[:width]
        for j, cell in enumerate(row):
            try:
                out[k, j] = _cell_float(cell)
            except ValueError:
                raise MocapError(
                    path,
                    take,
                    f"line {lineno}, {names[j] if j < len(names) else f'column {j + 1}'}",
                    f"'{cell.strip()}' is not a number",
                ) from None
    return out


def _csv_lines(path: Path) -> list[list[str]]:
    """The file's rows as CSV cells (a byte-order mark dropped, bad bytes replaced)."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except OSError as exc:
        raise MocapError(path, path.stem, "<file>", f"cannot read: {exc.strerror}") from None
    lines = text.splitlines()
    try:
        return list(csv.reader(lines))
    except csv.Error as exc:  # e.g. a cell longer than the csv module's field limit
        raise MocapError(path, path.stem, "<file>", f"not a CSV file ({exc})") from None


def _vicon_section(path: Path, take: str, lines: list[list[str]]) -> int:
    """Index of the 'Trajectories' row, with the four header rows under it."""
    start = next((i for i, r in enumerate(lines) if r and r[0].strip() == "Trajectories"), None)
    if start is None:
        raise MocapError(
            path, take, "Trajectories", "no 'Trajectories' section (export the trajectories from Nexus)"
        )
    if len(lines) < start + 5:
        raise MocapError(path, take, "Trajectories", "the section ends before its header rows")
    return start


def _vicon_labels(path: Path, take: str, start: int, names_row: list[str], cols_row: list[str]) -> list[str]:
    """The marker names over each X,Y,Z triple after 'Frame,Sub Frame' (Nexus 2 layout)."""
    if [c.strip() for c in cols_row[:2]] != ["Frame", "Sub Frame"]:
        raise MocapError(
            path, take, f"line {start + 4}", "expected 'Frame,Sub Frame,X,Y,Z,...' (Nexus 2 layout)"
        )
    labels = []
    for j in range(2, len(cols_row), 3):
        name = names_row[j].strip() if j < len(names_row) else ""
        if not name or [c.strip() for c in cols_row[j : j + 3]] != ["X", "Y", "Z"]:
            raise MocapError(
                path, take, f"line {start + 3}, column {j + 1}", "expected a marker name over X,Y,Z"
            )
        labels.append(name)
    return labels


def _vicon_unit(path: Path, take: str, start: int, units_row: list[str]) -> str:
    """The one length unit the units row gives every column."""
    units = {u.strip().lower() for u in units_row[2:] if u.strip()}
    if not units:
        raise MocapError(
            path, take, f"line {start + 5} (units)", "missing: the file does not say its length unit"
        )
    if len(units) > 1 or next(iter(units)) not in LENGTH_UNITS:
        raise MocapError(path, take, f"line {start + 5} (units)", f"unknown or mixed units {sorted(units)}")
    return next(iter(units))


def _vicon_rows(path: Path, take: str, lines: list[list[str]], first: int) -> list[tuple[int, list[str]]]:
    """The section's frame rows (line number, cells) from ``first`` to the blank line that ends it."""
    rows = []
    for i in range(first, len(lines)):
        if not lines[i] or not any(c.strip() for c in lines[i]):
            break  # a blank line ends the section
        rows.append((i + 1, lines[i]))
    if not rows:
        raise MocapError(path, take, "Trajectories", "no frames")
    return rows


def read_vicon_csv(path: Path) -> Take:
    take = path.stem
    lines = _csv_lines(path)
    start = _vicon_section(path, take, lines)
    rate = _rate(path, take, f"line {start + 2} (frame rate)", (lines[start + 1] or [""])[0])
    names_row, cols_row, units_row = lines[start + 2], lines[start + 3], lines[start + 4]
    labels = _vicon_labels(path, take, start, names_row, cols_row)
    unit = _vicon_unit(path, take, start, units_row)
    rows = _vicon_rows(path, take, lines, start + 5)
    names = ["Frame", "Sub Frame"] + [f"{lab} {a}" for lab in labels for a in "XYZ"]
    data = _numbers(path, take, rows, names, 2 + 3 * len(labels))
    xyz = data[:, 2:].reshape(len(rows), len(labels), 3) * LENGTH_UNITS[unit]
    return Take(path, take, "Vicon Nexus CSV", rate, tuple(labels), xyz, f"units row = '{unit}'")


# -- OptiTrack Motive CSV --------------------------------------------------------------------
def _cell(row: list[str], j: int) -> str:
    """Cell ``j`` of a header row, stripped; empty past the row's end."""
    return row[j].strip() if j < len(row) else ""


def _motive_meta(path: Path, take: str, head: list[str]) -> tuple[dict[str, str], str, float, float]:
    """Motive's key/value first line; the take's name, its rate (Hz) and metres per length unit."""
    meta = {head[i].strip(): head[i + 1].strip() for i in range(0, len(head) - 1, 2)}
    take = meta.get("Take Name") or take
    if "Export Frame Rate" not in meta:
        raise MocapError(path, take, "Export Frame Rate", "missing from the first line")
    rate = _rate(path, take, "Export Frame Rate", meta["Export Frame Rate"])
    unit = meta.get("Length Units", "").lower()
    if not unit:
        raise MocapError(
            path,
            take,
            "Length Units",
            f"missing (format version {meta.get('Format Version', '?')}): the file does not say its unit",
        )
    if unit not in _MOTIVE_UNITS:
        raise MocapError(
            path, take, "Length Units", f"unknown unit '{unit}'; accepted: Meters, Centimeters, Millimeters"
        )
    return meta, take, rate, _MOTIVE_UNITS[unit]


def _motive_layout(
    path: Path, take: str, lines: list[list[str]]
) -> tuple[list[str], list[str], list[str], list[str], list[tuple[int, list[str]]]]:
    """Motive's header rows (Type, Name, the property row, the axes row) and the frame rows
    (line number, cells) under them."""
    hdr = next((i for i, r in enumerate(lines) if r and r[0].strip() == "Frame"), None)
    if hdr is None or hdr < 4:
        raise MocapError(path, take, "Frame", "no 'Frame,Time (Seconds),...' row under the Type/Name/ID rows")
    kinds = {r[1].strip(): r for r in lines[1:hdr] if len(r) > 1 and r[1].strip() in ("Type", "Name", "ID")}
    if "Type" not in kinds or "Name" not in kinds:
        raise MocapError(path, take, "Type", "no 'Type' and 'Name' rows above the data (Motive layout 1.2x)")
    rows = [
        (i + 1, lines[i]) for i in range(hdr + 1, len(lines)) if lines[i] and any(c.strip() for c in lines[i])
    ]
    if not rows:
        raise MocapError(path, take, "Frame", "no frames")
    return kinds["Type"], kinds["Name"], lines[hdr - 1], lines[hdr], rows


def _motive_columns(
    types: list[str], names: list[str], props: list[str], axes: list[str]
) -> tuple[dict[str, list[tuple[str, int]]], dict[str, dict[str, int]]]:
    """Which columns hold each marker's position (axis, column), and each rigid body's columns
    by ``property:axis`` (``Rotation:X``, ``Mean Marker Error:``)."""
    markers: dict[str, list[tuple[str, int]]] = {}
    bodies: dict[str, dict[str, int]] = {}
    for j in range(2, len(axes)):
        kind, name, prop, ax = _cell(types, j), _cell(names, j), _cell(props, j), axes[j].strip()
        if kind == "Marker" and prop == "Position":
            markers.setdefault(name, []).append((ax, j))
        elif kind == "Rigid Body":
            cols = bodies.setdefault(name, {})
            key = f"{prop}:{ax}"
            if key in cols:  # a second body of that name: neither can be told apart
                cols[key + "#"] = j
            cols[key] = j
    return markers, bodies


def _motive_marker_xyz(path: Path, take: str, name: str, cols: list[tuple[str, int]]) -> list[int]:
    """The X, Y and Z columns of one marker's position, in that order: exactly one of each."""
    found = [ax for ax, _ in cols]
    if len(found) > 3 and sorted(found) == sorted("XYZ" * (len(found) // 3)):
        raise MocapError(
            path,
            take,
            f"{name} Position",
            f"{len(found) // 3} markers are named '{name}' (columns "
            f"{', '.join(str(j + 1) for _, j in cols)}): give each its own label in Motive",
        )
    if sorted(found) != ["X", "Y", "Z"]:
        raise MocapError(
            path,
            take,
            f"{name} Position",
            f"expected one X, Y and Z column, found {len(found)} ({', '.join(a or '?' for a in found)})",
        )
    by_axis = dict(cols)
    return [by_axis[a] for a in "XYZ"]


_MOTIVE_BODY = (
    "Rotation:X",
    "Rotation:Y",
    "Rotation:Z",
    "Rotation:W",
    "Position:X",
    "Position:Y",
    "Position:Z",
)
"""The columns a solved rigid body needs: its quaternion (x, y, z, w), then its position."""


def _motive_bodies(
    bodies: dict[str, dict[str, int]], data: np.ndarray, scale: float, rotation: str
) -> tuple[dict[str, RigidBody], dict[str, str]]:
    """The rigid bodies Motive solved, and those that cannot be used with the reason (a
    markers file that asks for one of those is refused with it)."""
    solved = {}
    unusable: dict[str, str] = {}
    for name, c in bodies.items():
        twice = sorted(k[:-1] for k in c if k.endswith("#"))
        if twice:
            unusable[name] = (
                f"two rigid bodies are named '{name}' in the file ({', '.join(twice)} twice): "
                "give each asset its own name in Motive"
            )
            continue
        if any(k not in c for k in _MOTIVE_BODY):
            unusable[name] = (
                f"its rotation is exported as '{rotation}': export quaternions (Rotation Type: Quaternion)"
                if rotation != "Quaternion"
                else "it lacks Rotation X,Y,Z,W or Position X,Y,Z columns"
            )
            continue
        err = (
            data[:, c["Mean Marker Error:"]] * scale
            if "Mean Marker Error:" in c
            else np.full(len(data), np.nan)
        )
        solved[name] = RigidBody(
            data[:, [c[k] for k in _MOTIVE_BODY[4:]]] * scale, data[:, [c[k] for k in _MOTIVE_BODY[:4]]], err
        )
    return solved, unusable


def read_motive_csv(path: Path) -> Take:
    lines = _csv_lines(path)
    meta, take, rate, scale = _motive_meta(path, path.stem, lines[0] if lines else [])
    types, names, props, axes, rows = _motive_layout(path, take, lines)
    width = len(axes)
    colnames = [
        f"{names[j] if j < len(names) else ''} {props[j] if j < len(props) else ''} {axes[j]}".strip()
        for j in range(width)
    ]
    markers, bodies = _motive_columns(types, names, props, axes)
    labels = tuple(markers)
    xyz_cols = [_motive_marker_xyz(path, take, m, markers[m]) for m in labels]
    data = _numbers(path, take, rows, colnames, width)
    xyz = np.stack([data[:, c] for c in xyz_cols], axis=1) * scale if labels else np.zeros((len(rows), 0, 3))
    solved, unusable = _motive_bodies(bodies, data, scale, meta.get("Rotation Type", "Quaternion"))
    return Take(
        path,
        take,
        f"OptiTrack Motive CSV {meta.get('Format Version', '')}".strip(),
        rate,
        labels,
        xyz,
        f"Length Units = '{meta['Length Units']}'",
        bodies=solved,
        unusable=unusable,
    )


# -- Qualisys TSV ----------------------------------------------------------------------------
def _qualisys_header(lines: list[str]) -> tuple[dict[str, list[str]], int]:
    """QTM's KEY<tab>values lines, and the index of the first line after them."""
    meta: dict[str, list[str]] = {}
    i = 0
    while i < len(lines):
        cells = lines[i].split("\t")
        key = cells[0].strip()
        if not key or key == "Frame" or _is_number(key):
            break
        meta[key] = [c.strip() for c in cells[1:]]
        i += 1
    return meta, i


def _qualisys_lead(lines: list[str], i: int) -> tuple[int, int]:
    """How many columns (Frame, Time) come before the markers', and the first frame line: QTM
    2019 and later write a column header row, older versions none."""
    if i < len(lines) and lines[i].split("\t")[0].strip() == "Frame":
        cols = [c.strip() for c in lines[i].split("\t")]
        return (2 if len(cols) > 1 and cols[1] == "Time" else 1), i + 1
    return 0, i


def _qualisys_labels(path: Path, take: str, names: list[str]) -> tuple[str, ...]:
    """The marker names, in the order of their X, Y, Z columns; an empty name between two
    others would shift every column after it."""
    while names and not names[-1]:
        names = names[:-1]
    if "" in names:
        raise MocapError(
            path,
            take,
            "MARKER_NAMES",
            f"marker {names.index('') + 1} has no name (an empty cell between names)",
        )
    return tuple(names)


def _qualisys_columns(
    path: Path, take: str, lines: list[str], first: int, lead: int, labels: tuple[str, ...]
) -> None:
    """The column header row (QTM 2019 and later), when there is one, must name each marker's
    X, Y, Z in the order MARKER_NAMES gives."""
    if lead == 0:
        return
    found = [c.strip() for c in lines[first - 1].split("\t")][lead:]
    while found and not found[-1]:
        found.pop()
    expected = [f"{m} {a}" for m in labels for a in "XYZ"]
    if found != expected:
        k = next(
            (k for k, (f, e) in enumerate(zip(found, expected, strict=False)) if f != e),
            min(len(found), len(expected)),
        )
        got = repr(found[k]) if k < len(found) else "nothing"
        want = repr(expected[k]) if k < len(expected) else "no more columns"
        raise MocapError(
            path,
            take,
            f"line {first}, column {lead + k + 1}",
            f"expected {want} (MARKER_NAMES, three columns X, Y, Z each), found {got}",
        )


def read_qualisys_tsv(path: Path) -> Take:
    take = path.stem
    try:
        lines = path.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    except OSError as exc:
        raise MocapError(path, take, "<file>", f"cannot read: {exc.strerror}") from None
    meta, i = _qualisys_header(lines)
    if "FREQUENCY" not in meta or "MARKER_NAMES" not in meta:
        raise MocapError(
            path,
            take,
            "FREQUENCY" if "FREQUENCY" not in meta else "MARKER_NAMES",
            "missing: not a Qualisys TSV 3D export (header KEY<tab>value lines)",
        )
    rate = _rate(path, take, "FREQUENCY", (meta["FREQUENCY"] or [""])[0])
    labels = _qualisys_labels(path, take, meta["MARKER_NAMES"])
    lead, i = _qualisys_lead(lines, i)
    _qualisys_columns(path, take, lines, i, lead, labels)
    rows = [(k + 1, lines[k].split("\t")) for k in range(i, len(lines)) if lines[k].strip()]
    if not rows:
        raise MocapError(path, take, "<data>", "no frames")
    names = ["Frame", "Time"][:lead] + [f"{m} {a}" for m in labels for a in "XYZ"]
    data = _numbers(path, take, rows, names, lead + 3 * len(labels))
    xyz = data[:, lead:].reshape(len(rows), len(labels), 3)
    xyz[(xyz == 0.0).all(axis=2)] = np.nan  # QTM writes a marker it did not see as 0, 0, 0
    return Take(
        path, take, "Qualisys TSV", rate, labels, xyz * 1e-3, "QTM TSV 3D export (millimetres by definition)"
    )


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
