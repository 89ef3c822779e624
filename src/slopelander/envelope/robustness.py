"""Robustness to the attitude at impact (paper Sec. V-E, Fig. 12).

Every cell keeps the preset chosen for a level landing and is flown ``draws`` times with a
pitch and a pitch rate drawn uniformly from +-10 deg and +-60 deg/s (fixed seed). A draw
succeeds when the vehicle lands (ideal, under-used or end of travel, Sec. V-A). The overall
rate is taken over the nominal envelope only, the cells whose level landing succeeds, as the
paper's "81 % of the landing envelope".
"""

from __future__ import annotations

import numpy as np

from slopelander.envelope.maps import LandingMap, model_record, preset_conditions
from slopelander.envelope.sweep import run_sweep
from slopelander.model import Model, Outcome

PITCH_RANGE_DEG = 10.0
PITCH_RATE_RANGE_DPS = 60.0


def robustness_map(
    presets: LandingMap,
    model: Model,
    *,
    draws: int = 10,
    seed: int = 0,
    pitch_range_deg: float = PITCH_RANGE_DEG,
    pitch_rate_range_dps: float = PITCH_RATE_RANGE_DPS,
    client=None,
    progress: bool | None = None,
) -> LandingMap:
    """Success rate per cell under random attitude at impact, with the presets of ``presets``.

    The result's fields: ``success_rate`` (0..1, per cell), ``nominal`` (1 where the level
    landing succeeds), the presets, and ``outcome`` (the level landing's). ``meta['overall']``
    is the success rate over every draw of the nominal cells.
    """
    if draws < 1:
        raise ValueError(f"draws must be at least 1, got {draws}")
    flown = model.rigid() if presets.meta.get("strategy", {}).get("rigid") else model
    base = preset_conditions(presets)
    rng = np.random.default_rng(seed)
    grid = np.repeat(base, draws)
    grid["pitch_deg"] = rng.uniform(-pitch_range_deg, pitch_range_deg, grid.size)
    grid["pitch_rate_dps"] = rng.uniform(-pitch_rate_range_dps, pitch_rate_range_dps, grid.size)
    res = run_sweep(grid, flown, client=client, progress=progress, desc="robustness")
    ok = (res["outcome"].astype(int) <= Outcome.END_OF_TRAVEL).reshape(*presets.axes.shape, draws)
    rate = ok.mean(axis=-1)
    nominal = presets.landed()
    overall = float(ok[nominal].mean()) if nominal.any() else float("nan")
    fields = {n: presets.fields[n].copy() for n in ("tau_up", "tau_down", "angle_up_deg", "angle_down_deg")}
    fields.update(outcome=presets.fields["outcome"].copy(), success_rate=rate, nominal=nominal.astype(float))
    meta = {
        **{k: v for k, v in presets.meta.items() if k != "model"},
        "model": model_record(flown),
        "draws_per_cell": draws,
        "seed": seed,
        "pitch_range_deg": pitch_range_deg,
        "pitch_rate_range_dps": pitch_rate_range_dps,
        "overall": overall,
        "nominal_cells": int(nominal.sum()),
        "landings": int(grid.size),
        "presets_kind": presets.kind,
    }
    return LandingMap("robustness", presets.axes, fields, meta)
