"""Writers of the exporters' real layouts, for the import tests: what Vicon Nexus 2.x,
OptiTrack Motive 2.x/3.x (CSV format 1.23) and Qualisys QTM (TSV 3D export) write."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def _cell(v: float, fmt: str = "{:.5f}") -> str:
    return fmt.format(v) if math.isfinite(v) else ""


def vicon_csv(path: Path, labels: list[str], xyz_m: np.ndarray, rate: float, subject: str = "quad") -> None:
    """Nexus 2 "Trajectories" export: section name, rate, Subject:Marker names over X,Y,Z,
    the Frame/Sub Frame header, the units row (mm), one row per frame, empty cells for gaps."""
    lines = ["Trajectories", f"{rate:g}"]
    lines.append(",," + ",".join(f"{subject}:{m},," for m in labels).rstrip(","))
    lines.append("Frame,Sub Frame," + ",".join("X,Y,Z" for _ in labels))
    lines.append(",," + ",".join("mm,mm,mm" for _ in labels))
    for f in range(xyz_m.shape[0]):
        cells = [_cell(v * 1000.0) for v in xyz_m[f].ravel()]
        lines.append(f"{f + 1},0," + ",".join(cells))
    path.write_text("\n".join(lines) + "\n")


def motive_csv(
    path: Path,
    labels: list[str],
    xyz_m: np.ndarray,
    rate: float,
    *,
    body: tuple[str, np.ndarray, np.ndarray] | None = None,
    units: str = "Meters",
) -> None:
    """Motive CSV 1.23: the key/value first line (rates, rotation type, length units), a blank
    line, the Type / Name / ID rows, the property row, Frame / Time (Seconds) / axes, then
    frames; a rigid body's Rotation X,Y,Z,W, Position X,Y,Z, Mean Marker Error come first.
    ``body``: (name, quaternions (frames, 4; x, y, z, w), positions (frames, 3) m)."""
    scale = {"Meters": 1.0, "Millimeters": 1000.0}[units]
    n = xyz_m.shape[0]
    head = (
        f"Format Version,1.23,Take Name,{path.stem},Take Notes,,Capture Frame Rate,{rate:.6f},"
        f"Export Frame Rate,{rate:.6f},Capture Start Time,2026-11-30 10.15.02.511 AM,Capture Start Frame,"
        f"48112,Total Frames in Take,{n},Total Exported Frames,{n},Rotation Type,Quaternion,"
        f"Length Units,{units},Coordinate Space,Global"
    )
    types, names, ids, props, axes = (
        ["", "Type"],
        ["", "Name"],
        ["", "ID"],
        ["", ""],
        ["Frame", "Time (Seconds)"],
    )
    cols = []
    if body is not None:
        name, quat, pos = body
        for ax, data in zip("XYZW", quat.T, strict=True):
            types.append("Rigid Body"), names.append(name), ids.append("1"), props.append("Rotation")
            axes.append(ax), cols.append((data, "{:.6f}"))
        for ax, data in zip("XYZ", pos.T, strict=True):
            types.append("Rigid Body"), names.append(name), ids.append("1"), props.append("Position")
            axes.append(ax), cols.append((data * scale, "{:.6f}"))
        types.append("Rigid Body"), names.append(name), ids.append("1"), props.append("Mean Marker Error")
        axes.append(""), cols.append((np.where(np.isfinite(pos[:, 0]), 0.0004 * scale, np.nan), "{:.6f}"))
    for k, m in enumerate(labels):
        for a in range(3):
            types.append("Marker"), names.append(m), ids.append(f"{9000 + k:X}"), props.append("Position")
            axes.append("XYZ"[a]), cols.append((xyz_m[:, k, a] * scale, "{:.6f}"))
    rows = [head, "", ",".join(types), ",".join(names), ",".join(ids), ",".join(props), ",".join(axes)]
    for f in range(n):
        rows.append(f"{f},{f / rate:.6f}," + ",".join(_cell(float(c[0][f]), c[1]) for c in cols))
    path.write_text("\n".join(rows) + "\n")


def qualisys_tsv(path: Path, labels: list[str], xyz_m: np.ndarray, rate: float) -> None:
    """QTM TSV 3D export with the column header row (QTM 2019 and later); a marker not seen
    in a frame is written as 0.000 0.000 0.000, as QTM does."""
    n = xyz_m.shape[0]
    lines = [
        f"NO_OF_FRAMES\t{n}",
        "NO_OF_CAMERAS\t12",
        f"NO_OF_MARKERS\t{len(labels)}",
        f"FREQUENCY\t{rate:g}",
        "NO_OF_ANALOG\t0",
        "ANALOG_FREQUENCY\t0",
        "DESCRIPTION\t--",
        "TIME_STAMP\t2026-11-30, 10:15:02.511\t4821.33741",
        "DATA_INCLUDED\t3D",
        "MARKER_NAMES\t" + "\t".join(labels),
        "TRAJECTORY_TYPES\t" + "\t".join("Measured" for _ in labels),
        "Frame\tTime\t" + "\t".join(f"{m} {a}" for m in labels for a in "XYZ"),
    ]
    mm = np.nan_to_num(xyz_m * 1000.0, nan=0.0)
    for f in range(n):
        lines.append(f"{f + 1}\t{f / rate:.5f}\t" + "\t".join(f"{v:.3f}" for v in mm[f].ravel()))
    path.write_text("\n".join(lines) + "\n")
