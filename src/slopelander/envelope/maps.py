"""A landing map (one outcome and preset per slope x speed cell), its files and its figures of merit.

A map is plain arrays on :class:`~slopelander.envelope.axes.MapAxes`, so the same object holds
the paper's Fig. 8 (one preset everywhere), Fig. 9-10 (a preset chosen per cell) and the
robustness map (a success rate per cell). It is written as NPZ (everything, reloadable) and
CSV (one row per cell, for a spreadsheet).
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from slopelander.envelope.axes import MapAxes
from slopelander.envelope.sweep import run_sweep
from slopelander.errors import SlopelanderError
from slopelander.model import RESULT_FIELDS, Model, Outcome, default_conditions

PRESET_FIELDS = ("tau_up", "tau_down", "angle_up_deg", "angle_down_deg")


class MapFileError(SlopelanderError):
    """A map file that cannot be read back."""


@dataclass
class LandingMap:
    """Per-cell arrays of shape ``axes.shape`` plus what produced them.

    ``fields`` always holds ``outcome`` (Outcome codes) and the presets flown
    (:data:`PRESET_FIELDS`); maps from simulations also hold every RESULT_FIELDS column.
    ``meta`` records the strategy, the model's parameters and effects, and free notes.
    """

    kind: str
    axes: MapAxes
    fields: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def outcome(self) -> np.ndarray:
        return self.fields["outcome"].astype(int)

    def ideal(self) -> np.ndarray:
        """Green cells: the only ones the paper's Fig. 11 counts."""
        return self.outcome == Outcome.IDEAL

    def landed(self) -> np.ndarray:
        """Every successful landing: ideal, under-used or end of travel (Sec. V-A)."""
        return self.outcome <= Outcome.END_OF_TRAVEL

    def mask(self, success: str = "ideal") -> np.ndarray:
        if success == "ideal":
            return self.ideal()
        if success == "landed":
            return self.landed()
        raise ValueError(f"success must be 'ideal' or 'landed', got {success!r}")

    # -- files ------------------------------------------------------------------------------
    def save(self, directory: str | Path, stem: str | None = None) -> tuple[Path, Path]:
        """Write ``<stem>.npz`` and ``<stem>.csv`` into ``directory``; return both paths."""
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        stem = stem or self.kind
        npz = directory / f"{stem}.npz"
        np.savez_compressed(
            npz,
            slope_deg=self.axes.slopes,
            speed=self.axes.speeds,
            meta=np.array(json.dumps({"kind": self.kind, **self.meta})),
            **{f"field_{k}": v for k, v in self.fields.items()},
        )
        path_csv = directory / f"{stem}.csv"
        names = list(self.fields)
        with path_csv.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["slope_deg", "speed", "outcome_name", *names])
            for i, s in enumerate(self.axes.slopes):
                for j, v in enumerate(self.axes.speeds):
                    code = int(self.fields["outcome"][i, j])
                    w.writerow(
                        [
                            f"{s:g}",
                            f"{v:g}",
                            Outcome(code).name.lower(),
                            *(_fmt(self.fields[n][i, j]) for n in names),
                        ]
                    )
        return npz, path_csv

    @classmethod
    def load(cls, path: str | Path) -> LandingMap:
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                axes = MapAxes(z["slope_deg"], z["speed"])
                fields = {k[6:]: z[k] for k in z.files if k.startswith("field_")}
        except (OSError, KeyError, ValueError) as exc:
            raise MapFileError(f"{path}: not a landing map file ({exc})") from None
        kind = meta.pop("kind", path.stem)
        return cls(kind, axes, fields, meta)


def _fmt(v: Any) -> str:
    v = float(v)
    return "" if np.isnan(v) else f"{v:.6g}"


# -- figures of merit -----------------------------------------------------------------------
def envelope_area(m: LandingMap, success: str = "ideal") -> float:
    """Area of the successful cells, deg x m/s (each cell counts slope step x speed step)."""
    return float(m.mask(success).sum()) * m.axes.cell_area


def max_slope(m: LandingMap, success: str = "ideal") -> float:
    """Steepest slope with at least one successful cell (NaN if none)."""
    ok = m.mask(success).any(axis=1)
    return float(m.axes.slopes[ok].max()) if ok.any() else float("nan")


def reach_per_speed(m: LandingMap, success: str = "ideal") -> np.ndarray:
    """Per speed: the steepest slope S such that every slope from the first up to S succeeds.

    This is the paper's "the envelope reaches 35-40 deg over the full velocity range": the
    unbroken reach from flat ground, NaN where even the first slope fails.
    """
    ok = m.mask(success)
    out = np.full(m.axes.speeds.size, np.nan)
    for j in range(ok.shape[1]):
        bad = np.flatnonzero(~ok[:, j])
        n = bad[0] if bad.size else ok.shape[0]
        if n > 0:
            out[j] = m.axes.slopes[n - 1]
    return out


def summary(m: LandingMap) -> dict[str, float]:
    """The numbers a reader compares with the paper, for both success definitions."""
    out: dict[str, float] = {}
    for s in ("ideal", "landed"):
        reach = reach_per_speed(m, s)
        out[f"max_slope_{s}_deg"] = max_slope(m, s)
        out[f"reach_{s}_min_deg"] = float(np.nanmin(reach)) if np.isfinite(reach).any() else float("nan")
        out[f"reach_{s}_max_deg"] = float(np.nanmax(reach)) if np.isfinite(reach).any() else float("nan")
        out[f"area_{s}_deg_mps"] = envelope_area(m, s)
    # cells per outcome class, by name (every class, zeros included, so a reader sees them all)
    for o in Outcome:
        out[f"cells_{o}"] = int((m.outcome == o).sum())
    return out


# -- flying given presets -------------------------------------------------------------------
def preset_conditions(m: LandingMap, **fixed: float) -> np.ndarray:
    """The conditions that fly each cell's preset at its own (slope, speed)."""
    n_s, n_v = m.axes.shape
    grid = default_conditions(n_s * n_v)
    grid["slope_deg"] = np.repeat(m.axes.slopes, n_v)
    grid["speed"] = np.tile(m.axes.speeds, n_s)
    for name in PRESET_FIELDS:
        grid[name] = m.fields[name].ravel()
    strategy = m.meta.get("strategy", {})
    for name in ("reverse_percent", "reverse_delay"):
        grid[name] = float(strategy.get(name, 0.0))
    if grid["reverse_percent"].any():  # a thrust that ends; files without it: held
        grid["reverse_duration"] = float(strategy.get("reverse_duration", math.inf))
        grid["reverse_ramp"] = float(strategy.get("reverse_ramp", 0.0))
    for name, value in fixed.items():
        grid[name] = value
    return grid


def results_to_fields(results: np.ndarray, shape: tuple[int, ...]) -> dict[str, np.ndarray]:
    return {n: results[n].reshape(shape) for n in RESULT_FIELDS}


def fly_presets(
    m: LandingMap, model: Model, *, kind: str | None = None, client=None, progress: bool | None = None
) -> LandingMap:
    """The same presets flown by another model (another parameter set): a new map."""
    if m.meta.get("strategy", {}).get("rigid"):
        model = model.rigid()
    results = run_sweep(preset_conditions(m), model, client=client, progress=progress, desc=kind or m.kind)
    fields = {n: m.fields[n].copy() for n in PRESET_FIELDS}
    fields.update(results_to_fields(results, m.axes.shape))
    meta = {**m.meta, "model": model_record(model), "presets_from": m.meta.get("model")}
    return LandingMap(kind or m.kind, m.axes, fields, meta)


def model_record(model: Model) -> dict[str, Any]:
    """What a map or table must carry to say which model produced it."""
    d = model.params.to_dict()
    rec = {
        "source": model.params.source,
        "effects": list(model.effects),
        "parameters": d["parameters"],
        "dt": model.dt,
    }
    if model.user_effects:  # their parameters recorded like the built-ins', with bounds
        rec["user_effects"] = {e.name: e.record() for e in model.user_effects}
    return rec
