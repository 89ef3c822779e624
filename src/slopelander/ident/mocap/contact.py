"""First contact and the impact state, from the body's free flight before it, or from foot markers.

A take starts in free flight. The flight is a parabola: the centre of mass's path is fitted by
a quadratic frame after frame until the next frames leave it by more than the noise (the
onset). The contact time is then placed between frames by two hinge fits on the vertical, free
fall before ``t_c`` and a departure after it, ``t_c`` scanned on a fine grid. Frames 5 ms apart
cannot show how the departure starts, and that shape sets where between frames ``t_c`` lands:
a deceleration that starts as a step and grows ((t - t_c)^2 and ^3 terms) is the smoothest
start, and places contact early on the truth simulator's landings (1-1.5 ms: the feet's impact
takes some speed at once); a sudden loss of speed and then a steady deceleration ((t - t_c)
and ^2) is the sharpest, and places it late by about as much. The contact time is the middle
of the two; its 68 % half-width adds the noise's share (each fit's sum of squares rising by one
noise variance) to the bracket's, the truth taken as anywhere between them (width / sqrt 12).
On the truth simulator's landings this is centred within 0.1 ms and holds the truth at about
its stated rate (benchmarks/import_accuracy.py). The impact state (vertical and horizontal
speed, pitch and pitch rate) is the flight's fit evaluated at ``t_c``: no differentiation of
noisy frames.

With markers on the feet (the markers file's ``feet``), contact is where the first foot marker
reaches the roof: each foot's height above the roof over its last free-flight frames, fitted
with the free fall's known acceleration along the roof's normal, is extrapolated to the
marker's height at touch (:func:`foot_contact`); its uncertainty is the fit's at that instant
over the foot's approach speed. This needs no model of how the body decelerates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

GRAVITY = 9.81
MIN_FLIGHT = 8
"""Frames of free flight a take needs before contact."""


@dataclass(frozen=True)
class Flight:
    onset: int
    """Index of the first frame that left the free-flight parabola."""
    accel: np.ndarray
    """m/s^2, the flight's fitted acceleration (capture axes): -g times the vertical."""
    frames: int
    """Frames (seen) the flight fit used."""


def find_flight(t: np.ndarray, p: np.ndarray, noise: float) -> Flight | None:
    """The free flight at the start of ``p`` (frames, 3) and the first frame that leaves it;
    None when fewer than :data:`MIN_FLIGHT` seen frames precede the onset or none leaves it.

    The next three seen frames must all leave the parabola fitted so far by more than 4.5 times
    their expected scatter (the noise and the extrapolation's own uncertainty, per axis): an
    impact's deviation grows frame after frame, a noisy frame does not."""
    ok = np.flatnonzero(np.isfinite(p[:, 0]))
    ahead = 3
    k = MIN_FLIGHT
    while k + ahead <= ok.size:
        idx = ok[:k]
        t0 = t[idx[0]]
        a = np.column_stack([np.ones(k), t[idx] - t0, 0.5 * (t[idx] - t0) ** 2])
        coef = np.linalg.lstsq(a, p[idx], rcond=None)[0]
        nxt = ok[k : k + ahead]
        an = np.column_stack([np.ones(ahead), t[nxt] - t0, 0.5 * (t[nxt] - t0) ** 2])
        spread = np.sqrt(np.einsum("ij,jk,ik->i", an, np.linalg.inv(a.T @ a), an))  # per unit noise
        dev = np.linalg.norm(p[nxt] - an @ coef, axis=1)
        if (dev > 4.5 * noise * np.sqrt(3.0 * (1.0 + spread**2)) + 2e-4).all():
            return Flight(int(ok[k]), coef[2], k)
        k += 1
    return None


@dataclass(frozen=True)
class Contact:
    time: float
    """s on the take's clock (frame 0 at 0)."""
    sd: float
    """s: the contact time's 68 % half-width."""
    frames_used: int


def _hinge(
    t: np.ndarray, z: np.ndarray, onset: int, rate: float, powers: tuple[int, ...]
) -> tuple[float, float, int]:
    """One hinge fit: the best ``t_c`` (s from the onset frame), its noise-only 68 % half-width
    and the frames used; the departure after ``t_c`` is a sum of (t - t_c)^p over ``powers``."""
    dt = 1.0 / rate
    after = max(3, round(0.015 * rate))
    lo = max(0, onset - max(MIN_FLIGHT, round(0.05 * rate)))
    sel = np.arange(lo, min(len(t), onset + after + 1))
    sel = sel[np.isfinite(z[sel])]
    tt = t[sel] - t[onset]
    y = z[sel] + 0.5 * GRAVITY * tt * tt
    grid = np.arange(-4.0, 0.0 + 1e-9, 1.0 / 50.0) * dt
    ssr = np.empty(len(grid))
    for i, tc in enumerate(grid):
        h = np.clip(tt - tc, 0.0, None)
        a = np.column_stack([np.ones_like(tt), tt] + [h**p for p in powers])
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        r = y - a @ coef
        ssr[i] = float(r @ r)
    best = int(np.argmin(ssr))
    var = ssr[best] / max(len(tt) - 3 - len(powers), 1)
    inside = grid[ssr <= ssr[best] + var]
    sd = max(float(inside.max() - inside.min()) / 2.0, dt / 50.0)
    return float(grid[best]), sd, len(sel)


SMOOTH_START = (2, 3)
"""The departure's powers when the deceleration starts as a step: contact placed early."""
SHARP_START = (1, 2)
"""The powers when the speed drops at once, then a steady deceleration: contact placed late."""


def contact_time(t: np.ndarray, z: np.ndarray, onset: int, rate: float) -> Contact:
    """First contact from the vertical ``z`` around the onset: the middle of the smooth-start and
    sharp-start hinge fits, whose half-width holds the noise and the unseen start's shape (see
    the module docstring)."""
    early, sd_early, used = _hinge(t, z, onset, rate, SMOOTH_START)
    late, sd_late, _ = _hinge(t, z, onset, rate, SHARP_START)
    noise = 0.5 * math.hypot(sd_early, sd_late)
    shape = abs(late - early) / math.sqrt(12.0)  # the truth anywhere between the two
    return Contact(float(t[onset] + 0.5 * (early + late)), math.hypot(noise, shape), used)


def flight_state(
    t: np.ndarray, y: np.ndarray, tc: float, accel: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """Value and rate at ``tc`` of the columns of ``y`` over flight frames ``t`` (< tc), fitted
    with the known acceleration ``accel`` per column (0 for pitch, -g u for the position)."""
    ok = np.isfinite(y).all(axis=1) & (t < tc)
    tt = t[ok] - tc
    target = y[ok] - 0.5 * np.outer(tt * tt, np.broadcast_to(accel, (y.shape[1],)))
    a = np.column_stack([np.ones_like(tt), tt])
    coef = np.linalg.lstsq(a, target, rcond=None)[0]
    return coef[0], coef[1]


def flight_residual(t: np.ndarray, y: np.ndarray, tc: float, accel: np.ndarray | float) -> np.ndarray:
    """Standard deviation of each column's flight frames about their free-flight fit."""
    ok = np.isfinite(y).all(axis=1) & (t < tc)
    tt = t[ok] - tc
    value, rate = flight_state(t, y, tc, accel)
    pred = value + np.outer(tt, rate) + 0.5 * np.outer(tt * tt, np.broadcast_to(accel, (y.shape[1],)))
    return np.sqrt(np.sum((y[ok] - pred) ** 2, axis=0) / max(int(ok.sum()) - 2, 1))


FOOT_FRAMES = 12
"""Free-flight frames before a foot's touch its height is fitted over."""


@dataclass(frozen=True)
class FootContact(Contact):
    foot: int
    """Index (in the markers file's ``feet``) of the foot that touched first."""


def foot_contact(t: np.ndarray, height: np.ndarray, g_normal: float, noise: float) -> FootContact | None:
    """First contact from foot markers: ``height`` (frames, feet) is each marker's height above
    its height at touch (m, along the roof's normal), ``g_normal`` the free fall's acceleration
    along that normal (m/s^2, positive towards the roof), ``noise`` a marker's jitter (m). None
    when no foot is seen for 3 frames in flight before it comes within 3 noise of the roof."""
    best: FootContact | None = None
    for j in range(height.shape[1]):
        h = height[:, j]
        near = np.flatnonzero(np.isfinite(h) & (h <= 3.0 * noise))
        if not near.size:
            continue
        k0 = int(near[0])
        idx = np.arange(max(0, k0 - FOOT_FRAMES), k0)
        idx = idx[np.isfinite(h[idx])]
        if idx.size < 3:
            continue
        tau = t[idx] - t[k0]
        a = np.column_stack([np.ones_like(tau), tau])
        y = h[idx] + 0.5 * g_normal * tau * tau
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        c0, c1 = float(coef[0]), float(coef[1])
        # c0 + c1 tau - g/2 tau^2 = 0: the root where the approaching foot arrives
        roots = np.roots([-0.5 * g_normal, c1, c0]) if g_normal else np.array([-c0 / c1])
        roots = roots[np.isreal(roots)].real
        ahead = roots[roots > tau[-1]]
        if not ahead.size:
            continue
        tc = float(ahead.min())
        speed = abs(c1 - g_normal * tc)
        r = y - a @ coef
        sd_fit = max(noise, float(np.sqrt(r @ r / max(idx.size - 2, 1))))
        v = np.array([1.0, tc])
        var = float(v @ np.linalg.inv(a.T @ a) @ v) * sd_fit**2
        sd = math.sqrt(var) / max(speed, 1e-6)
        tc += float(t[k0])
        if best is None or tc < best.time:
            best = FootContact(tc, sd, int(idx.size), j)
    return best
