"""The model observed as a recording observed the landing: at its sample times (less a lag),
free flight before contact, rates made the way the recording's were."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from slopelander.ident.mocap.rates import savgol_rates
from slopelander.ident.recording import Drop
from slopelander.ident.synth import ballistic, centred_rates, extend
from slopelander.model import LandingConditions, Model, Outcome, simulate
from slopelander.model.landing import STATE_COLUMNS

_COLUMNS = np.array(STATE_COLUMNS)


def predict(
    model: Model, drop: Drop, *, outcome: bool = True, lag: float = 0.0
) -> tuple[np.ndarray, Outcome | None]:
    """The model's states at the drop's sample times (free flight before contact) and, with
    ``outcome``, its predicted outcome over the model's full horizon. When the recording's rates
    were differentiated from its positions, the model's are too, the same way. ``lag`` (s): the
    recording's frames show the body this long before their time stamps (:func:`observe`)."""
    tr = trajectory(model, drop, outcome=outcome, reach=max(0.0, -lag))
    return observe(tr, model, drop, lag), (tr.result.outcome if outcome else None)


def trajectory(model: Model, drop: Drop, *, outcome: bool = False, reach: float = 0.0):
    """The model's landing on the drop's conditions, long enough to observe the drop ``reach``
    seconds later than its last sample (and over the model's full horizon with ``outcome``)."""
    h = (drop.rate_window or 0) // 2
    horizon = float(extend(drop.t, h)[-1]) + 0.01 + reach
    if outcome:
        horizon = max(horizon, model.criteria.horizon)
    return simulate(drop.conditions, _with_horizon(model, horizon), sample_rate=400.0, full_horizon=True)


def observe(tr, model: Model, drop: Drop, lag: float = 0.0) -> np.ndarray:
    """The landing ``tr`` (:func:`trajectory`) as the drop's recording saw it: at its sample times
    less ``lag``, free flight before contact, rates made as the recording's were."""
    h = (drop.rate_window or 0) // 2
    t = extend(drop.t, h)  # a recording's rates are centred on its first and last samples too
    tm = t - lag if lag else t
    raw = tr.raw  # the states' columns read straight from it (tr.states would copy them first)
    tc = np.clip(tm, 0, None)
    after = np.empty((len(t), 6))
    for i, c in enumerate(STATE_COLUMNS):
        after[:, i] = np.interp(tc, tr.t, raw[:, c])
    if tr.t[-1] < tm[-1] - 1e-9:  # the integrator stopped early: hold its last state
        after[tm > tr.t[-1]] = raw[-1, _COLUMNS]
    pre = tm < 0
    if pre.any():
        z0 = float(raw[0, STATE_COLUMNS[1]])
        g = model.params["gravity"]
        after[pre] = (
            ballistic(drop.conditions, tm[pre], z0, g) if lag else _flight(drop.conditions, tm[pre], z0, g)
        )
    if drop.rate_window:  # observe the model as the recording was observed
        rates = centred_rates(after[:, :3], t, drop.rate_window)
        after = after[h : len(t) - h]
        after[:, 3:] = rates
    elif drop.savgol:
        after[:, 3:] = savgol_rates(after[:, :3], drop.savgol[2], *drop.savgol[:2])
    return after


_FLIGHTS: dict[tuple, tuple[LandingConditions, np.ndarray]] = {}
_FLIGHTS_MAX = 1024


def _flight(cond: LandingConditions, t: np.ndarray, z0: float, gravity: float) -> np.ndarray:
    """:func:`ballistic`, kept per conditions, times, start height and gravity (exact values):
    a fit changes neither the drops nor, mostly, the vehicle's height at impact."""
    key = (id(cond), t.dtype.str, t.tobytes(), float(z0).hex(), float(gravity).hex())
    hit = _FLIGHTS.get(key)
    if hit is None or hit[0] is not cond:
        hit = (cond, ballistic(cond, t, z0, gravity))
        hit[1].setflags(write=False)
        if len(_FLIGHTS) >= _FLIGHTS_MAX:
            _FLIGHTS.clear()
        _FLIGHTS[key] = hit
    return hit[1]


_variant: tuple[Model, str, Model] | None = None
"""The last (model, horizon as its exact hex, model with that horizon): a fit predicts every
drop of a set with one model, and the drops mostly share their length."""


def _with_horizon(model: Model, horizon: float) -> Model:
    """``model`` simulated to ``horizon`` s after impact (the same copy for the same model)."""
    global _variant
    v = _variant
    exact = float(horizon).hex()
    if v is not None and v[0] is model and v[1] == exact:
        return v[2]
    m = replace(model, criteria=replace(model.criteria, horizon=horizon))
    _variant = (model, exact, m)
    return m
