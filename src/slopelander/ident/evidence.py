"""The statistics behind diagnose's verdict: a test over drops, the noise floor, what is visible.

Drops are the independent units (each has its own measurement noise; the samples inside one
drop are not independent: motion-capture rates are slopes over several samples). Every drop is
predicted by fits that did not see it (cross-fitting), so a candidate's gain on drop i,

    d_i = log(error of the base on drop i / error with the candidate on drop i),

is the gain of a model the drop did not shape. With nothing missing, a candidate's extra
parameters fit the training drops' noise and gain nothing on a drop they did not see (a
little less than nothing on average), so d_i is as likely negative as positive. The test flips
the signs of the drops' gains at random (all 2^n patterns for up to 16 drops) and asks how
often the best candidate's mean gain is at least the one observed: the maximum over candidates
is taken in every pattern, so the p-value is corrected for trying several candidates (Westfall
and Young's max-statistic), which are far from independent. The gains share one unit (a log
error ratio), so the plain mean is used: studentised, a candidate with tiny but equal gains on
every drop reached huge values in the flipped patterns and hid a real effect that acts on some
drops more than others (a viscous joint at -44 % held-out error read p = 0.077).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from itertools import product

import numpy as np

from slopelander.ident.compare import WEIGHTS, combine, masked_rms
from slopelander.ident.mocap.rates import savgol_rates
from slopelander.ident.observe import predict
from slopelander.ident.recording import Drop
from slopelander.ident.synth import centred_rates, extend
from slopelander.model import Model

MIN_GAIN = 0.02
"""A candidate must also lower the held-out NRMSE by this fraction: on control sets the test
alone passed candidates that gained 0.03-0.6 %, the same for several at once (a refit's extra
search improving the base parameters, shared by all drops of a group), never a real effect."""

EXACT_UP_TO = 16
"""Drops up to which every sign pattern is enumerated; beyond, :data:`RANDOM_FLIPS` are drawn."""
RANDOM_FLIPS = 20000


def weighted_mse(per_state: np.ndarray) -> float:
    """A drop's error as the fit weighs it: mean of the states' squared NRMSE, angular x2."""
    return float(np.sum(WEIGHTS * np.asarray(per_state) ** 2) / WEIGHTS.sum())


@dataclass(frozen=True)
class SignFlipTest:
    """Max-statistic sign-flip test of the candidates' per-drop held-out gains."""

    t: np.ndarray
    """Mean gain per candidate (the test's statistic)."""
    p: np.ndarray
    """Family-wise p-value per candidate (corrected for trying them all)."""
    patterns: int
    exact: bool
    critical: float
    """The mean gain a candidate must reach at the test's level (the 1 - alpha quantile of
    the best candidate's under sign flips)."""


def sign_flip_test(gains: np.ndarray, alpha: float = 0.05, seed: int = 0) -> SignFlipTest:
    """``gains``: candidates x drops. One-sided: a candidate helps on drops it did not see."""
    gains = np.atleast_2d(np.asarray(gains, dtype=float))
    n = gains.shape[1]
    if n <= EXACT_UP_TO:
        signs = np.array(list(product((1.0, -1.0), repeat=n)))
        exact = True
    else:
        rng = np.random.default_rng(seed)
        signs = np.vstack([np.ones(n), rng.choice((1.0, -1.0), (RANDOM_FLIPS, n))])
        exact = False
    t_obs = gains.mean(axis=1)
    max_t = (signs @ gains.T / n).max(axis=1)  # patterns: the best candidate's mean gain
    p = np.array([float(np.mean(max_t >= t - 1e-12)) for t in t_obs])
    crit = float(np.quantile(max_t, 1.0 - alpha))
    return SignFlipTest(t_obs, p, len(signs), exact, crit)


def names_missing(
    candidates: dict[str, tuple[float, float]], base: float, floor: float | None, alpha: float
) -> str | None:
    """The candidate named missing, or None: of those whose held-out gains pass the test
    (family-wise p <= ``alpha``) and lower the held-out NRMSE by at least :data:`MIN_GAIN`,
    the one with the largest gain. ``candidates``: name -> (held-out NRMSE, p); ``base``: the
    base model's held-out NRMSE; ``floor``: the noise floor's NRMSE (None: not declared)."""
    passed = {
        n: 1.0 - h / base for n, (h, p) in candidates.items() if p <= alpha and 1.0 - h / base >= MIN_GAIN
    }
    return max(passed, key=passed.__getitem__) if passed else None


# -- the noise floor ------------------------------------------------------------------------
def noise_of(drop: Drop) -> dict[str, float] | None:
    """The recording's declared measurement noise (``meta.noise``), or None if not declared."""
    raw = drop.meta.get("noise") if isinstance(drop.meta, dict) else None
    if not isinstance(raw, dict):
        return None
    try:
        return {
            "position_sd_m": float(raw["position_sd_m"]),
            "angle_sd_deg": float(raw["angle_sd_deg"]),
            "latency_s": float(raw.get("latency_s", 0.0)),
        }
    except (KeyError, TypeError, ValueError):
        return None


def noise_floor(
    model: Model, drops: list[Drop], ranges: np.ndarray, draws: int = 2, seed: int = 0
) -> float | None:
    """NRMSE that the declared measurement noise alone leaves between a perfect model and its
    recording: the model's own landing, recorded as the drop was (its latency, jitter and rate
    differentiation), against the same landing observed without noise. None when a drop does
    not declare its noise."""
    noises = [noise_of(d) for d in drops]
    if any(n is None for n in noises):
        return None
    rng = np.random.default_rng(seed)
    out = []
    for d, nz in zip(drops, noises, strict=True):
        assert nz is not None
        clean, _ = predict(model, d, outcome=False)
        w = d.rate_window
        h = (w or 0) // 2
        te = extend(d.t, h)  # the recording's rates are centred on its first and last samples
        frames = replace(d, t=te - nz["latency_s"], states=np.zeros((len(te), 6)), meta={})
        shifted, _ = predict(model, frames, outcome=False)
        contact = d.t >= 0
        vals = []
        for _ in range(draws):
            pos_e = shifted[:, :3].copy()
            pos_e[:, :2] += rng.normal(0.0, nz["position_sd_m"], (len(te), 2))
            pos_e[:, 2] += rng.normal(0.0, math.radians(nz["angle_sd_deg"]), len(te))
            pos = pos_e[h : len(te) - h]
            if w:
                rates = centred_rates(pos_e, te, w)
            elif d.savgol:
                rates = savgol_rates(pos, d.savgol[2], *d.savgol[:2])
            else:
                rates = shifted[h : len(te) - h, 3:]
            rec = np.column_stack([pos, rates])
            err = (rec - clean)[contact] / ranges
            err[~np.isfinite(d.states[contact])] = np.nan  # the recording's gaps are not scored
            vals.append(combine(masked_rms(err)))
        out.append(float(np.mean(vals)))
    return float(np.mean(out))
