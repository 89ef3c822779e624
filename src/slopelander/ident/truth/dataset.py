"""Datasets of the independent truth: one hidden effect (or none), optionally a departure of the
base physics from the model's, recorded by motion capture."""

from __future__ import annotations

import numpy as np

from slopelander.ident.recording import Drop
from slopelander.ident.truth.mocap import MotionCapture, record
from slopelander.ident.truth.physics import Departure, HiddenEffect, truth_states
from slopelander.model import LandingConditions, Model


def truth_dataset(
    model: Model,
    conditions: list[LandingConditions],
    hidden: HiddenEffect | None = None,
    mocap: MotionCapture | None = None,
    *,
    seed: int = 0,
    duration: float = 0.6,
    cache: dict | None = None,
    departure: Departure | None = None,
) -> list[Drop]:
    """One recorded drop per condition of ``model`` plus ``hidden`` (None: the model itself),
    integrated by solve_ivp and observed by ``mocap`` with noise drawn from ``seed``.

    ``cache`` (a dict) keeps each landing's dense truth between calls: the integration is the
    slow part (10-30 s a drop), and a new noise seed on the same drops needs none.
    ``departure``: the truth's base physics departs from ``model``'s that way."""
    mocap = mocap or MotionCapture()
    rng = np.random.default_rng(seed)
    grid = np.arange(-0.06, duration + 0.01, 1.0 / 4000.0)
    out = []
    for i, cond in enumerate(conditions):
        key = (
            hidden.name if hidden else None,
            tuple(sorted((hidden.values if hidden else {}).items())),
            cond,
            duration,
            *((departure.name,) if departure and departure.name != "exact" else ()),
        )
        if cache is None or key not in cache:
            states, outcome = truth_states(model, cond, grid, hidden, departure=departure)
            if cache is not None:
                cache[key] = (states, outcome)
        else:
            states, outcome = cache[key]

        def truth(t: np.ndarray, states: np.ndarray = states) -> np.ndarray:
            return np.column_stack([np.interp(t, grid, states[:, c]) for c in range(6)])

        how = (f", hidden {hidden.name}" if hidden else "") + (
            f", base departs: {departure.name}" if departure and departure.name != "exact" else ""
        )
        src = f"independent truth (solve_ivp{how}), motion capture"
        out.append(
            record(f"drop{i:02d}", cond, truth, outcome, mocap, rng, duration=duration, source=src, seed=seed)
        )
    return out
