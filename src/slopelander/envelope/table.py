"""Writing the preset lookup table the companion flies with (read by slopelander.controller.table).

Per (slope, impact speed) cell: the chosen uphill/downhill torques and leg angles, the outcome
the model predicts, and two measures of how far that is from failing:

* ``margin`` (0..1): the fraction of the cell's neighbourhood -- the cell and its up to eight
  neighbours one grid step away in slope and/or speed -- in which the cell's *own* preset still
  lands (ideal, under-used or end of travel). It answers the controller's question "if my slope
  or speed estimate is one step off, does this preset still work?". A cell whose own landing
  fails has margin 0. The loader picks the safe neighbour by it.
* ``spare_travel`` (0..1): 1 - the larger peak compression of the two legs, the travel left.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path
from typing import Any

import numpy as np
import yaml

import slopelander
from slopelander.controller.table import SCHEMA
from slopelander.envelope.axes import MapAxes
from slopelander.envelope.maps import PRESET_FIELDS, LandingMap, preset_conditions
from slopelander.envelope.presets import STRATEGIES, Strategy, StrategyError, choose_presets
from slopelander.envelope.sweep import run_sweep
from slopelander.model import Model, Outcome, default_conditions

NEIGHBOURS = tuple((di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj)

MARGIN_DEFINITION = (
    "fraction of the cell and its up to 8 grid neighbours (one step in slope and/or speed) "
    "where the cell's own preset lands (ideal, under-used or end of travel); 0 if the cell's "
    "own landing fails"
)


def neighbour_margin(
    presets: LandingMap, model: Model, *, client=None, progress: bool | None = None
) -> np.ndarray:
    """The ``margin`` of every cell (see the module docstring)."""
    flown = model.rigid() if presets.meta.get("strategy", {}).get("rigid") else model
    n_s, n_v = presets.axes.shape
    base = preset_conditions(presets).reshape(n_s, n_v)
    rows, owners = [], []
    for di, dj in NEIGHBOURS:
        i = np.arange(max(0, -di), min(n_s, n_s - di))
        j = np.arange(max(0, -dj), min(n_v, n_v - dj))
        if not (i.size and j.size):
            continue
        ii, jj = np.meshgrid(i, j, indexing="ij")
        g = base[ii, jj].copy()  # this cell's preset ...
        g["slope_deg"] = presets.axes.slopes[ii + di]  # ... flown at the neighbour's condition
        g["speed"] = presets.axes.speeds[jj + dj]
        rows.append(g.ravel())
        owners.append(np.ravel_multi_index((ii.ravel(), jj.ravel()), (n_s, n_v)))
    grid = np.concatenate(rows) if rows else default_conditions(0)
    owner = np.concatenate(owners) if owners else np.zeros(0, int)
    res = run_sweep(grid, flown, client=client, progress=progress, desc="margins")
    ok = res["outcome"].astype(int) <= Outcome.END_OF_TRAVEL
    own = presets.landed().ravel()
    good = own.astype(float) + np.bincount(owner, weights=ok, minlength=n_s * n_v)
    total = 1.0 + np.bincount(owner, minlength=n_s * n_v)
    return np.where(own, good / total, 0.0).reshape(n_s, n_v)


def build_table(
    model: Model,
    axes: MapAxes,
    strategy: Strategy | str = "rvt",
    *,
    client=None,
    progress: bool | None = None,
    command: str | None = None,
) -> tuple[dict[str, Any], LandingMap]:
    """Choose the presets, compute margins, and return the table document and the map.

    The table sets FSA legs; the stock rigid gear has nothing to set (and can be damaged, an
    outcome no table cell may hold), so a rigid strategy is refused."""
    name = strategy if isinstance(strategy, str) else strategy.name
    if (name in STRATEGIES and STRATEGIES[name].rigid) or (not isinstance(strategy, str) and strategy.rigid):
        raise StrategyError(f"strategy {name!r} flies the stock rigid gear: a lookup table sets FSA legs")
    presets = choose_presets(model, axes, strategy, client=client, progress=progress)
    margin = neighbour_margin(presets, model, client=client, progress=progress)
    presets.fields["margin"] = margin
    spare = 1.0 - np.maximum(presets.fields["compression_up"], presets.fields["compression_down"])
    presets.fields["spare_travel"] = np.clip(np.nan_to_num(spare), 0.0, 1.0)
    return table_document(presets, command=command), presets


def _rows(a: np.ndarray, digits: int) -> list[list[float]]:
    return [[round(float(v), digits) for v in row] for row in a]


def table_document(presets: LandingMap, *, command: str | None = None) -> dict[str, Any]:
    """The YAML document (schema ``slopelander.lookup-table/1``) for a map with margins."""
    names = np.array([o.name.lower() for o in Outcome])
    cells: dict[str, Any] = {f: _rows(presets.fields[f], 4) for f in PRESET_FIELDS}
    cells["outcome"] = [list(map(str, row)) for row in names[presets.outcome]]
    cells["margin"] = _rows(presets.fields["margin"], 4)
    cells["spare_travel"] = _rows(presets.fields["spare_travel"], 4)
    model = presets.meta["model"]
    return {
        "schema": SCHEMA,
        "created": _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(),
        "generator": {
            "package": f"slopelander {slopelander.__version__}",
            **({"command": command} if command else {}),
        },
        "strategy": {**presets.meta["strategy"], "description": presets.meta["description"]},
        "margin_definition": MARGIN_DEFINITION,
        "axes": {
            "slope_deg": [float(v) for v in presets.axes.slopes],
            "speed": [float(v) for v in presets.axes.speeds],
        },
        "cells": cells,
        "model": {
            "source": model["source"],
            "effects": model["effects"],
            "dt": model["dt"],
            "parameters": model["parameters"],
            **({"user_effects": model["user_effects"]} if model.get("user_effects") else {}),
        },
    }


def write_table(doc: dict[str, Any], path: str | Path) -> Path:
    """Write a table document as YAML (rows in flow style: one line per slope)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = (
        "# slopelander preset lookup table; schema: docs/lookup-table.md\n"
        "# cells.<field>: one row per slope (axes.slope_deg), one value per speed (axes.speed)\n"
    )
    path.write_text(
        header
        + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=10_000, allow_unicode=True)
    )
    return path
