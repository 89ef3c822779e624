"""Synthetic drops: what a motion-capture system would have recorded of a "truth" model.

The workflow is proven on drops whose truth is known (a model with an effect the analysed
model lacks), so the noise must look like real motion capture: positions and angles jittered,
rates differentiated from those noisy positions (as a mocap export does), a small latency.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.lib.stride_tricks import as_strided, sliding_window_view

from slopelander.ident.recording import Drop
from slopelander.model import LandingConditions, Model, Outcome, simulate

PAPER_TORQUE_LEVELS = (0.56, 1.1, 1.7, 2.3)
"""Friction torques per real joint the paper's drops and maps use, N*m."""


@dataclass(frozen=True)
class NoiseModel:
    """Motion-capture-like measurement noise (defaults: a good lab system at 200 Hz)."""

    position_sd: float = 1e-3
    """m, white noise on x and z."""
    angle_sd_deg: float = 0.3
    """deg, white noise on pitch."""
    latency: float = 0.002
    """s, the recording shows the state this long ago."""
    sample_rate: float = 200.0
    rate_window: int = 7
    """Samples of the least-squares slope that turns positions into rates (motion-capture
    software differentiates over a short window; 7 samples = 30 ms at 200 Hz)."""

    @classmethod
    def none(cls, sample_rate: float = 200.0) -> NoiseModel:
        return cls(0.0, 0.0, 0.0, sample_rate)

    def __post_init__(self) -> None:
        for name in ("position_sd", "angle_sd_deg", "latency"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"noise {name} must be a finite number >= 0")
        if not (10.0 <= self.sample_rate <= 2400.0):
            raise ValueError("noise sample_rate must lie within 10..2400 Hz")
        if self.rate_window < 3 or self.rate_window % 2 == 0:
            raise ValueError("noise rate_window must be an odd number of samples >= 3")


def differentiate(x: np.ndarray, t: np.ndarray, window: int = 7) -> np.ndarray:
    """Rates of sampled positions (columns of ``x``) by the least-squares slope over ``window``
    samples centred on each one, fitted against the samples' own times (a recording that lost
    frames has gaps; a slope on a uniform grid would then misread them); ``window`` 3 is the
    central difference. Where the centred window does not fit (the first and last
    ``window // 2`` samples), the slope of the line through the first or last ``window``
    samples: as little noise as inside (the differences there had 3.7 to 7.4 times the noise).
    A recording's own rates are centred there too, from the frames beyond it
    (:func:`centred_rates`)."""
    h = window // 2
    if len(t) <= window:
        return np.gradient(x, t, axis=0)
    n, c = x.shape
    if n != len(t):
        raise ValueError(f"differentiate: {n} samples but {len(t)} times")
    # every column at once: windows (n - window + 1, c, window) of x, multiplied into a
    # C-contiguous product so that each window's sum runs over the same contiguous run as a
    # single column's did (the same floats: the summation order decides them)
    row, col = x.strides
    windows = as_strided(x, (n - window + 1, c, window), (row, col, row), writeable=False)
    slopes = np.multiply(_slope_coef(t, window)[:, None, :], windows, order="C").sum(axis=2)
    out = np.empty_like(x, dtype=x.dtype if np.issubdtype(x.dtype, np.inexact) else np.float64)
    out[h:-h] = slopes
    out[:h] = slopes[0]
    out[-h:] = slopes[-1]
    return out


def extend(t: np.ndarray, n: int) -> np.ndarray:
    """``t`` with ``n`` more times before its first and after its last, at its ends' spacing."""
    if n <= 0 or len(t) < 2:
        return t
    k = np.arange(n, 0, -1)
    return np.concatenate([t[0] - k * (t[1] - t[0]), t, t[-1] + k[::-1] * (t[-1] - t[-2])])


def centred_rates(pos: np.ndarray, t: np.ndarray, window: int) -> np.ndarray:
    """Rates at the middle ``len(t) - 2 * (window // 2)`` samples of ``pos`` over times ``t``
    (a recording's samples with ``window // 2`` frames beyond each end, as :func:`extend`
    makes): a window centred on every sample of the recording, its first and last included.
    This is what ``meta.rates`` ``lsq_slope`` declares, so the model is observed so too."""
    h = window // 2
    return differentiate(pos, t, window)[h : len(t) - h]


_COEF: dict[tuple, np.ndarray] = {}
_COEF_MAX = 256


def _slope_coef(t: np.ndarray, window: int) -> np.ndarray:
    """Per window, the weights whose dot product with the samples is the least-squares slope.
    They depend on the times alone, and a fit differentiates the model at the same drop's
    times thousands of times: kept per times (by value) and window."""
    key = (window, t.dtype.str, t.shape, t.tobytes())
    coef = _COEF.get(key)
    if coef is None:
        tw = sliding_window_view(t, window)  # (n - window + 1, window)
        tc = tw - tw.mean(axis=1, keepdims=True)
        coef = tc / (tc * tc).sum(axis=1, keepdims=True)
        coef.setflags(write=False)
        if len(_COEF) >= _COEF_MAX:
            _COEF.clear()
        _COEF[key] = coef
    return coef


PAPER_SLOPES = (0.0, 45.0)
"""deg: the slopes of the paper's drops."""
PAPER_SPEEDS = (1.0, 3.0)
"""m/s: the vertical impact speeds of the paper's drops."""


def paper_drops(
    n: int = 10,
    seed: int = 0,
    *,
    slopes: tuple[float, float] = PAPER_SLOPES,
    speeds: tuple[float, float] = PAPER_SPEEDS,
) -> list[LandingConditions]:
    """``n`` drop conditions over the paper's spread: slopes 0..45 deg, 1..3 m/s, joint torques
    from the paper's levels, full leg extension. Slopes and speeds are stratified so that even
    a small set spans the range; steep fast drops on soft joints are the ones that flip.
    ``slopes`` and ``speeds`` narrow the spread (an effect that acts only where feet slide is
    seen on the steep part of it); they must lie within the paper's."""
    if n < 1:
        raise ValueError("need at least one drop")
    for name, (lo, hi), (plo, phi) in (("slopes", slopes, PAPER_SLOPES), ("speeds", speeds, PAPER_SPEEDS)):
        if not (plo <= lo < hi <= phi):
            raise ValueError(f"{name} {lo}..{hi} must be an interval within the paper's {plo}..{phi}")
    rng = np.random.default_rng(seed)
    slopes_ = slopes[0] + (np.arange(n) + rng.uniform(0.1, 0.9, n)) * (slopes[1] - slopes[0]) / n
    speeds_ = speeds[0] + (speeds[1] - speeds[0]) * (rng.permutation(n) + rng.uniform(0.1, 0.9, n)) / n
    out = []
    for s, v in zip(slopes_, speeds_, strict=True):
        up, down = rng.choice(PAPER_TORQUE_LEVELS, 2)
        out.append(
            LandingConditions(
                slope_deg=round(float(s), 1), speed=round(float(v), 2), tau_up=float(up), tau_down=float(down)
            )
        )
    return out


def survived(
    model: Model, conditions: list[LandingConditions], horizon: float = 1.0
) -> list[LandingConditions]:
    """The conditions on which ``model`` does not flip within ``horizon`` seconds.

    A flip ends the model's simulation, and a synthetic recording of it then holds still; a
    set of drops meant to show a friction law is better made of drops the vehicle survives."""
    t = np.array([0.0, horizon])
    return [c for c in conditions if true_states(model, c, t)[1] is not Outcome.FLIP]


def ballistic(cond: LandingConditions, t: np.ndarray, z0: float, gravity: float = 9.81) -> np.ndarray:
    """States of unpowered flight before first contact (t < 0), ending at the impact state."""
    pitch0 = math.radians(cond.pitch_deg)
    rate = math.radians(cond.pitch_rate_dps)
    return np.column_stack(
        [
            cond.horizontal_speed * t,
            z0 - cond.speed * t - 0.5 * gravity * t**2,
            pitch0 + rate * t,
            np.full_like(t, cond.horizontal_speed),
            -cond.speed - gravity * t,
            np.full_like(t, rate),
        ]
    )


def true_states(model: Model, cond: LandingConditions, t: np.ndarray):
    """The model's states at times ``t`` (flight for t < 0) and the landing's outcome."""
    horizon = max(model.criteria.horizon, float(t[-1]) + 0.05)
    m = replace(model, criteria=replace(model.criteria, horizon=horizon))
    tr = simulate(cond, m, sample_rate=1200.0, full_horizon=True)
    after = np.column_stack([np.interp(np.clip(t, 0, None), tr.t, tr.states[:, i]) for i in range(6)])
    before = ballistic(cond, t, float(tr.states[0, 1]), model.params["gravity"])
    return np.where((t < 0)[:, None], before, after), tr.result.outcome


def synthesize(
    model: Model,
    conditions: list[LandingConditions],
    noise: NoiseModel | None = None,
    *,
    seed: int = 0,
    duration: float = 1.0,
    before: float = 0.05,
    source: str = "synthetic",
) -> list[Drop]:
    """One recorded drop per condition: the truth ``model``'s landing sampled with ``noise``
    from ``before`` seconds ahead of first contact to ``duration`` seconds after it."""
    noise = noise or NoiseModel()
    rng = np.random.default_rng(seed)
    dt = 1.0 / noise.sample_rate
    t = np.arange(-round(before / dt), round(duration / dt) + 1) * dt
    drops = []
    # the frames beyond the recording's ends that its first and last rates are centred on
    h = noise.rate_window // 2
    te = extend(t, h)
    for i, cond in enumerate(conditions):
        truth_e, outcome = true_states(model, cond, te - noise.latency)
        truth = truth_e[h : len(te) - h]
        pos_e = truth_e[:, :3].copy()
        pos = pos_e[h : len(te) - h]  # a view: the recording's own frames
        pos[:, :2] += rng.normal(0.0, noise.position_sd, (len(t), 2)) if noise.position_sd else 0.0
        if noise.angle_sd_deg:
            pos[:, 2] += rng.normal(0.0, math.radians(noise.angle_sd_deg), len(t))
        noisy = noise.position_sd > 0 or noise.angle_sd_deg > 0
        if noisy:  # the frames beyond, from a generator of their own (the recording's draws as before)
            out = np.r_[0:h, len(te) - h : len(te)]
            beyond = rng.spawn(1)[0]
            pos_e[out, :2] += beyond.normal(0.0, noise.position_sd, (2 * h, 2))
            pos_e[out, 2] += beyond.normal(0.0, math.radians(noise.angle_sd_deg), 2 * h)
        rates = centred_rates(pos_e, te, noise.rate_window) if noisy else truth[:, 3:]
        meta = {"rates": {"method": "lsq_slope", "window": noise.rate_window}} if noisy else {}
        meta["noise"] = {
            "position_sd_m": noise.position_sd,
            "angle_sd_deg": noise.angle_sd_deg,
            "latency_s": noise.latency,
            "seed": seed,
        }
        drops.append(Drop(f"drop{i:02d}", t, np.column_stack([pos, rates]), cond, outcome, source, meta))
    return drops
