"""The slope under the vehicle, measured from what it already has: points on the surface from the
downward rangefinder, each reading placed with the attitude (heading included) and the local
position of its own moment, and a robust plane fitted through them: both gradients, the fall line
(the way the surface falls steepest) and the slope along the vehicle's heading, the planar
model's x.

Pure and numpy-only: it runs on the companion. How it works, what it cannot see and how far it
is to be trusted: docs/slope-estimate.md.

* :class:`SurfaceTrack` keeps the recent DISTANCE_SENSOR, ATTITUDE and LOCAL_POSITION_NED messages
  (fed every message, e.g. as a :meth:`Link.add_listener`) and turns each range reading into a
  point with the attitude and position interpolated to the reading's stamp (none within the
  window: the reading is dropped; a reading out of the sensor's range is no point).
* :func:`fit_plane` is the robust plane fit: a least-absolute-deviations start, then iteratively
  reweighted least squares with Tukey's biweight on a MAD scale; :func:`fit_line` the same along
  one direction (a Theil-Sen start).
* :func:`estimate_plane` fits the points near the landing spot and says why it will not be trusted
  (too few points, one direction only seen, one side of the spot unseen, many outliers, two
  different slopes on the two sides of the spot, too uncertain); :meth:`PlaneEstimate.along` gives
  the slope along a heading and the cross-slope the legs' plane does not see. :func:`estimate` is
  the older fit along north alone (a pass flown along north; kept for the tools that synthesize
  such passes). A refused estimate carries no slope to land on: the caller refuses, it does not
  guess.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections import deque
from dataclasses import dataclass, field

import numpy as np

#: Tukey's biweight constant (95 % efficiency at the normal) and the MAD's normal consistency
TUKEY_C = 4.685
MAD_NORMAL = 1.4826
#: the residual scale is never taken below this (m): noiseless points would give a zero scale, and
#: DISTANCE_SENSOR reports whole centimetres, so on a steady height most residuals are 0 or one
#: step: the MAD is then 0, and a step (1 cm) must stay well inside Tukey's cut (4.685 scales)
SCALE_FLOOR_M = 0.005
#: a point whose final weight is below this is counted as an outlier
OUTLIER_WEIGHT = 0.1
#: contiguous blocks of the block jackknife (points along a track are correlated within a block)
JACKKNIFE_BLOCKS = 8
#: a point belongs to the leg along a direction when it lies within this of the line through the
#: spot along it (m): a leg may be flown up to 0.3 m beside the spot (survey.ACROSS_SPOT_M)
LEG_BAND_M = 0.35
#: the second direction the points are seen along is at least this far from the first (deg)
SECOND_DIRECTION_DEG = 45.0
#: MAV_SENSOR_ROTATION_PITCH_270: the downward rangefinder
DOWNWARD = 25


@dataclass(frozen=True)
class EstimateSettings:
    """What :func:`estimate` needs from the settings (``slope.*`` in default_config.yaml)."""

    min_points: int = 30
    min_baseline_m: float = 1.0
    #: the spot must be seen on both sides, at least this far (m)
    min_side_m: float = 0.3
    #: points farther than this from the spot along north are not used (m)
    half_span_m: float = 1.5
    min_inlier_fraction: float = 0.7
    max_sigma_deg: float = 3.0
    sigma_floor_deg: float = 0.5
    attitude_error_deg: float = 1.0
    #: the position's height error as a random walk (m per sqrt(s)): it wanders slowly, so it is
    #: shared by neighbouring points and no per-point scatter or time-block jackknife sees it
    height_walk_m: float = 0.01
    #: the two sides' slopes may differ by this much beyond their joint 3 sigma (deg)
    plane_tolerance_deg: float = 4.0

    @classmethod
    def from_config(cls, cfg) -> EstimateSettings:
        return cls(
            min_points=int(cfg["slope.min_points"]),
            min_baseline_m=float(cfg["slope.min_baseline_m"]),
            min_side_m=float(cfg["slope.min_side_m"]),
            half_span_m=float(cfg["slope.half_span_m"]),
            min_inlier_fraction=float(cfg["slope.min_inlier_fraction"]),
            max_sigma_deg=float(cfg["slope.max_sigma_deg"]),
            sigma_floor_deg=float(cfg["slope.sigma_floor_deg"]),
            attitude_error_deg=float(cfg["slope.attitude_error_deg"]),
            height_walk_m=float(cfg["slope.height_walk_m"]),
            plane_tolerance_deg=float(cfg["slope.plane_tolerance_deg"]),
        )


@dataclass(frozen=True)
class LineFit:
    """``h = intercept + gradient * x`` (h up); ``weights`` per point (0..1), ``scale_m`` the
    residuals' robust scale, ``gradient_se`` the gradient's standard error from the weighted fit."""

    intercept: float
    gradient: float
    weights: np.ndarray
    scale_m: float
    gradient_se: float


@dataclass
class SlopeEstimate:
    """The slope along the vehicle's heading (deg; positive: the surface falls the way the vehicle
    faces, as it must to land: the planar model's x) with its 1-sigma uncertainty, or the reason
    there is none (``refusal``). ``points``: (t, along the heading m, height up m, weight) of every
    point fitted (from a plane fit: the height less the cross-slope's share, so that the points
    show the section along the heading). Without a heading (``heading_deg`` None) the slope is
    along north from a line fit. From a plane fit the estimate also carries the plane: its slope
    down the fall line and the fall line's azimuth (deg from north, clockwise), and the cross-slope
    along the heading (deg, positive: falling to the vehicle's right)."""

    slope_deg: float | None
    sigma_deg: float | None
    refusal: str | None
    spot_x_m: float
    n_points: int = 0
    n_inliers: int = 0
    baseline_m: float = 0.0
    scale_m: float | None = None
    sides_deg: tuple[float, float] | None = None
    points: list[tuple[float, float, float, float]] = field(default_factory=list)
    heading_deg: float | None = None
    cross_deg: float | None = None
    cross_sigma_deg: float | None = None
    plane_slope_deg: float | None = None
    plane_sigma_deg: float | None = None
    fall_azimuth_deg: float | None = None
    fall_azimuth_sigma_deg: float | None = None
    spot_ne_m: tuple[float, float] | None = None

    @property
    def ok(self) -> bool:
        return self.refusal is None

    @property
    def needs_survey(self) -> bool:
        """Refused for want of points, not for what the points showed: a survey pass may help."""
        return self.refusal is not None and self.refusal.startswith(LACK)

    def plane_text(self) -> str:
        """The plane in words: its slope, where it falls, and across the heading."""
        if self.plane_slope_deg is None or self.fall_azimuth_deg is None:
            return ""
        text = (
            f"the surface falls {self.plane_slope_deg:.1f} +/- {self.plane_sigma_deg:.1f} deg toward "
            f"{az_text(self.fall_azimuth_deg)}"
        )
        if self.heading_deg is not None and self.cross_deg is not None:
            side = "right" if self.cross_deg >= 0 else "left"
            text += (
                f"; heading {round(self.heading_deg) % 360} deg: {self.slope_deg:.1f} deg along it, "
                f"{abs(self.cross_deg):.1f} deg across (to its {side})"
            )
        return text

    def describe(self) -> str:
        if not self.ok:
            return f"slope not measured: {self.refusal}"
        text = f"{self.slope_deg:.1f} +/- {self.sigma_deg:.1f} deg ({self.n_inliers}/{self.n_points} points)"
        if self.heading_deg is not None:
            text += f" along heading {round(self.heading_deg) % 360} deg"
            if self.cross_deg is not None:
                text += f", {self.cross_deg:+.1f} deg across"
        return text

    def record(self) -> dict:
        """The JSON form written to the landing's record."""

        def r(v: float | None, nd: int = 3) -> float | None:
            return None if v is None else round(v, nd)

        out = {
            "slope_deg": r(self.slope_deg),
            "sigma_deg": r(self.sigma_deg),
            "refusal": self.refusal,
            "spot_x_m": round(self.spot_x_m, 3),
            "n_points": self.n_points,
            "n_inliers": self.n_inliers,
            "baseline_m": round(self.baseline_m, 3),
            "scale_m": r(self.scale_m, 4),
            "sides_deg": None if self.sides_deg is None else [round(s, 2) for s in self.sides_deg],
            "points": [[round(t, 3), round(x, 4), round(h, 4), round(w, 3)] for t, x, h, w in self.points],
        }
        if self.plane_slope_deg is not None or self.heading_deg is not None:
            out.update(
                heading_deg=r(self.heading_deg, 2),
                cross_deg=r(self.cross_deg),
                cross_sigma_deg=r(self.cross_sigma_deg),
                plane_slope_deg=r(self.plane_slope_deg),
                plane_sigma_deg=r(self.plane_sigma_deg),
                fall_azimuth_deg=r(self.fall_azimuth_deg, 2),
                fall_azimuth_sigma_deg=r(self.fall_azimuth_sigma_deg, 2),
                spot_ne_m=None if self.spot_ne_m is None else [round(v, 3) for v in self.spot_ne_m],
            )
        return out


def az_text(azimuth_deg: float) -> str:
    """An azimuth as whole degrees, 0..359, and its compass point: "90 deg (east)"."""
    return f"{round(azimuth_deg) % 360} deg ({compass(azimuth_deg)})"


def compass(azimuth_deg: float) -> str:
    """The nearest of the 8 compass points to an azimuth (deg from north, clockwise)."""
    names = ("north", "north-east", "east", "south-east", "south", "south-west", "west", "north-west")
    return names[round((azimuth_deg % 360.0) / 45.0) % 8]


def wrap_deg(angle: float) -> float:
    """An angle (deg) in -180..180."""
    return (angle + 180.0) % 360.0 - 180.0


#: refusals that more points could cure start with this
LACK = "too little seen"


def beam_point(
    range_m: float, roll: float, pitch: float, yaw: float, north: float, east: float, down: float
) -> tuple[float, float, float]:
    """Where a downward beam of ``range_m`` from a body at (north, east, down) with this attitude
    (rad, ArduPilot's Euler 321) meets the surface: the body's z axis in NED is the third column
    of the body-to-NED rotation."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    zn = cr * sp * cy + sr * sy
    ze = cr * sp * sy - sr * cy
    zd = cr * cp
    return north + range_m * zn, east + range_m * ze, down + range_m * zd


def _interp(stamps: list[float], values: list[tuple], t: float, window: float) -> tuple | None:
    """``values`` at ``t`` linearly between the two stamps around it, both within ``window``;
    else the nearest within ``window``; else None."""
    i = bisect_left(stamps, t)
    lo = i - 1 if i > 0 else None
    hi = i if i < len(stamps) else None
    if lo is not None and hi is not None and t - stamps[lo] <= window and stamps[hi] - t <= window:
        t0, t1 = stamps[lo], stamps[hi]
        if t1 <= t0:
            return values[hi]
        f = (t - t0) / (t1 - t0)
        return tuple(a + f * (b - a) for a, b in zip(values[lo], values[hi], strict=True))
    best = None
    for j in (lo, hi):
        if j is not None and abs(stamps[j] - t) <= window and (best is None or abs(stamps[j] - t) < best[0]):
            best = (abs(stamps[j] - t), values[j])
    return None if best is None else best[1]


class SurfaceTrack:
    """The recent range readings, attitudes and positions, kept by vehicle time; feed it every
    message (:meth:`feed`), ask it for surface points (:meth:`points`)."""

    def __init__(self, window_s: float = 0.1, keep: int = 4000) -> None:
        self.window_s = window_s
        self.ranges: deque = deque(maxlen=keep)  # (t, distance m)
        self.attitudes: deque = deque(maxlen=keep)  # (t, (roll, pitch, yaw))
        self.positions: deque = deque(maxlen=keep)  # (t, (n, e, d))
        self.dropped = 0

    def feed(self, msg) -> None:
        kind = msg.get_type()
        if kind == "DISTANCE_SENSOR":
            if msg.orientation != DOWNWARD:
                return
            t = msg.time_boot_ms / 1000.0
            if msg.min_distance < msg.current_distance < msg.max_distance:  # in range: a surface
                self.ranges.append((t, msg.current_distance / 100.0))
        elif kind == "ATTITUDE":
            att = (msg.roll, msg.pitch, msg.yaw)
            if all(math.isfinite(a) for a in att):
                _insert(self.attitudes, msg.time_boot_ms / 1000.0, att)
        elif kind == "LOCAL_POSITION_NED":
            pos = (msg.x, msg.y, msg.z)
            if all(math.isfinite(p) for p in pos):
                _insert(self.positions, msg.time_boot_ms / 1000.0, pos)

    def add(self, t: float, range_m: float | None = None, attitude=None, position=None) -> None:
        """Add samples directly (offline evaluation, tests): each given part at vehicle time ``t``."""
        if range_m is not None:
            self.ranges.append((t, range_m))
        if attitude is not None:
            _insert(self.attitudes, t, tuple(attitude))
        if position is not None:
            _insert(self.positions, t, tuple(position))

    def points(self, since_s: float = -math.inf) -> list[tuple[float, float, float]]:
        """(t, north m, height up m) of each range reading since ``since_s`` whose attitude and
        position are known within the window; the others are dropped (counted in ``dropped``)."""
        return [(t, n, h) for t, n, _e, h in self.surface_points(since_s)]

    def surface_points(self, since_s: float = -math.inf) -> list[tuple[float, float, float, float]]:
        """(t, north m, east m, height up m) of each range reading since ``since_s`` whose attitude
        and position are known within the window; the others are dropped (``dropped``)."""
        at, av = [a[0] for a in self.attitudes], [a[1] for a in self.attitudes]
        pt, pv = [p[0] for p in self.positions], [p[1] for p in self.positions]
        out, self.dropped = [], 0
        for t, d in sorted(self.ranges):
            if t < since_s:
                continue
            att = _interp_attitude(at, av, t, self.window_s)
            pos = _interp(pt, pv, t, self.window_s)
            if att is None or pos is None:
                self.dropped += 1
                continue
            n, e, down = beam_point(d, *att, *pos)
            out.append((t, n, e, -down))
        return out

    def position(self) -> tuple[float, float, float] | None:
        """The newest position (north, east, down)."""
        return self.positions[-1][1] if self.positions else None

    def heading_deg(self) -> float | None:
        """The newest heading (ATTITUDE yaw, deg from north, clockwise, 0..360)."""
        return math.degrees(self.attitudes[-1][1][2]) % 360.0 if self.attitudes else None


def _interp_attitude(stamps: list[float], values: list[tuple], t: float, window: float) -> tuple | None:
    """:func:`_interp` for (roll, pitch, yaw): the yaw taken the short way across +-180 deg."""
    i = bisect_left(stamps, t)
    if 0 < i < len(stamps):
        y0, y1 = values[i - 1][2], values[i][2]
        if abs(y1 - y0) > math.pi:  # the two samples straddle the wrap: interpolate unwrapped
            y1 += -2 * math.pi if y1 > y0 else 2 * math.pi
            lo, hi = values[i - 1], (*values[i][:2], y1)
            return _interp([stamps[i - 1], stamps[i]], [lo, hi], t, window)
    return _interp(stamps, values, t, window)


def _insert(dq: deque, t: float, value: tuple) -> None:
    """Append in time order (a reordered, older message is put in its place)."""
    if not dq or t >= dq[-1][0]:
        dq.append((t, value))
        return
    items = list(dq)
    i = bisect_left([s for s, _ in items], t)
    items.insert(i, (t, value))
    dq.clear()
    dq.extend(items[-dq.maxlen :] if dq.maxlen else items)


def theil_sen(x: np.ndarray, h: np.ndarray, max_pairs: int = 20000) -> tuple[float, float]:
    """The median of the pairwise gradients (a strided subset of pairs when there are many) and
    the median intercept: a start that half the points being wrong does not move."""
    n = x.size
    i, j = np.triu_indices(n, 1)
    if i.size > max_pairs:
        keep = np.linspace(0, i.size - 1, max_pairs).astype(int)
        i, j = i[keep], j[keep]
    dx = x[j] - x[i]
    ok = np.abs(dx) > 1e-6
    if not ok.any():
        return float(np.median(h)), 0.0
    g = float(np.median((h[j] - h[i])[ok] / dx[ok]))
    return float(np.median(h - g * x)), g


def fit_line(x: np.ndarray, h: np.ndarray, iterations: int = 30) -> LineFit:
    """Robust ``h = a + b x``: Theil-Sen start, then IRLS with Tukey's biweight on the MAD scale
    of the residuals (re-estimated each round, floored at :data:`SCALE_FLOOR_M`)."""
    x = np.asarray(x, float)
    h = np.asarray(h, float)
    if x.size < 2:
        raise ValueError("a line needs at least two points")
    a, b = theil_sen(x, h)
    w = np.ones_like(x)
    s = SCALE_FLOOR_M
    for _ in range(iterations):
        r = h - (a + b * x)
        s = max(SCALE_FLOOR_M, MAD_NORMAL * float(np.median(np.abs(r - np.median(r)))))
        u = r / (TUKEY_C * s)
        w = np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)
        sw = w.sum()
        if sw <= 0 or np.count_nonzero(w) < 2:
            break
        xm = float((w * x).sum() / sw)
        sxx = float((w * (x - xm) ** 2).sum())
        if sxx <= 1e-12:
            break
        nb = float((w * (x - xm) * (h - (w * h).sum() / sw)).sum() / sxx)
        na = float((w * h).sum() / sw - nb * xm)
        done = abs(nb - b) < 1e-9 and abs(na - a) < 1e-9
        a, b = na, nb
        if done:
            break
    r = h - (a + b * x)
    sw = float(w.sum())
    xm = float((w * x).sum() / sw) if sw > 0 else 0.0
    sxx = float((w * (x - xm) ** 2).sum())
    neff = float(np.count_nonzero(w > OUTLIER_WEIGHT))
    var = float((w * r * r).sum() / max(1.0, sw)) * neff / max(1.0, neff - 2.0)
    se = math.sqrt(max(var, SCALE_FLOOR_M**2) / sxx) if sxx > 0 else math.inf
    return LineFit(a, b, w, s, se)


def _deg(gradient: float) -> float:
    """The slope (deg, positive falling toward north) of ``h = a + gradient x``."""
    return math.degrees(math.atan(-gradient))


def _deg_se(gradient: float, se: float) -> float:
    return math.degrees(se / (1.0 + gradient * gradient))


def walk_gradient_se(t: np.ndarray, x: np.ndarray, w: np.ndarray, walk: float) -> float:
    """The gradient's standard error from a height error that is a random walk of ``walk`` m per
    sqrt(s) (covariance ``walk^2 min(t_i, t_j)``) under the weighted fit ``w``. The gradient is
    ``sum c_i h_i`` with ``sum c_i = 0``, so its variance is ``walk^2`` times the integral over time
    of ``S(s)^2``, ``S(s)`` the sum of the ``c_i`` of the points after ``s``: a pass that sees the
    same ground going out and coming back cancels much of a slow drift, one sweep does not."""
    sw = float(w.sum())
    if sw <= 0 or walk <= 0:
        return 0.0
    xm = float((w * x).sum() / sw)
    sxx = float((w * (x - xm) ** 2).sum())
    if sxx <= 0:
        return math.inf
    order = np.argsort(t, kind="stable")
    c = (w * (x - xm) / sxx)[order]
    ts = t[order]
    after = np.cumsum(c[::-1])[::-1]  # after[k]: sum of c from k on
    gaps = np.diff(ts)  # between point k and k + 1 the points after s are k + 1 ..
    return walk * math.sqrt(float((gaps * after[1:] ** 2).sum()))


def _line_coverage_refusal(
    n: int, baseline_m: float, behind: float, ahead: float, st: EstimateSettings
) -> str | None:
    """Why ``n`` points spanning ``baseline_m`` (``behind`` and ``ahead`` of the spot, m) are too
    few or too short a stretch to fit the slope from, or None."""
    if n < st.min_points:
        return f"{LACK}: {n} points, {st.min_points} needed"
    if baseline_m < st.min_baseline_m:
        return f"{LACK}: the points span {baseline_m:.2f} m, {st.min_baseline_m:g} m needed"
    if min(behind, ahead) < st.min_side_m:
        side = "south" if behind < ahead else "north"
        return (
            f"{LACK}: surface seen only {min(behind, ahead):.2f} m {side} of the spot "
            f"({st.min_side_m:g} m needed; an edge or a gutter there?)"
        )
    return None


def _line_jackknife_deg(t: np.ndarray, x: np.ndarray, h: np.ndarray, baseline_m: float) -> float:
    """The slope's block jackknife error (deg) in time order, leaving out each block that still
    leaves a quarter of the baseline; inf with fewer than 3 such fits."""
    order = np.argsort(t)
    leave = []
    for b in np.array_split(order, JACKKNIFE_BLOCKS):
        keep = np.ones(x.size, bool)
        keep[b] = False
        if np.ptp(x[keep]) > 0.25 * baseline_m and keep.sum() >= 2:
            leave.append(_deg(fit_line(x[keep], h[keep]).gradient))
    k = len(leave)
    return (
        math.sqrt((k - 1) / k * float(np.sum((np.array(leave) - np.mean(leave)) ** 2)))
        if k >= 3
        else math.inf
    )


def estimate(
    points: list[tuple[float, float, float]], spot_x_m: float, settings: EstimateSettings | None = None
) -> SlopeEstimate:
    """The slope along north at the landing spot (north ``spot_x_m``) from ``points`` (t, north,
    height up), or a refusal saying why not. The uncertainty (1 sigma) is the root sum of squares
    of: the statistical error, the larger of the block jackknife of the fit over
    :data:`JACKKNIFE_BLOCKS` runs of consecutive points and the weighted fit's own standard error
    together with what the height's slow wander (``height_walk_m``, :func:`walk_gradient_se`)
    gives (points along a track share it: neither the scatter nor the jackknife sees all of it);
    the attitude's bias (``attitude_error_deg``: a pitch bias d moves the slope by sin^2(slope) d
    at level flight); and a floor (``sigma_floor_deg``)."""
    st = settings or EstimateSettings()
    near = [p for p in points if abs(p[1] - spot_x_m) <= st.half_span_m]
    est = SlopeEstimate(None, None, None, spot_x_m, n_points=len(near))
    if not near:
        est.refusal = f"{LACK}: no rangefinder point within {st.half_span_m:g} m of the spot"
        return est
    arr = np.array(near, float)
    t, x, h = arr[:, 0], arr[:, 1], arr[:, 2]
    est.baseline_m = float(x.max() - x.min())
    behind, ahead = spot_x_m - float(x.min()), float(x.max()) - spot_x_m
    est.points = [(float(a), float(b), float(c), 1.0) for a, b, c in near]
    est.refusal = _line_coverage_refusal(len(near), est.baseline_m, behind, ahead, st)
    if est.refusal is not None:
        return est
    fit = fit_line(x, h)
    est.points = [
        (float(a), float(b), float(c), float(w)) for (a, b, c), w in zip(near, fit.weights, strict=True)
    ]
    est.scale_m = fit.scale_m
    est.n_inliers = int(np.count_nonzero(fit.weights > OUTLIER_WEIGHT))
    slope = _deg(fit.gradient)
    est.slope_deg = slope
    frac = est.n_inliers / len(near)
    if frac < st.min_inlier_fraction:
        est.refusal = (
            f"only {frac:.0%} of {len(near)} points lie on one plane "
            f"({st.min_inlier_fraction:.0%} needed): the surface under the pass is not flat"
        )
        return est
    # the two sides of the spot: one plane has one slope (a ridge or a gutter under the path does not)
    sides = _side_slopes(t, x, h, (x < spot_x_m, x >= spot_x_m), st)
    if len(sides) == 2:
        est.sides_deg = (sides[0][0], sides[1][0])
        diff = abs(sides[0][0] - sides[1][0])
        allowed = 3.0 * math.hypot(sides[0][1], sides[1][1]) + st.plane_tolerance_deg
        if diff > allowed:
            est.refusal = (
                f"the surface is not one plane: {sides[0][0]:.1f} deg south of the spot, "
                f"{sides[1][0]:.1f} deg north of it (a ridge or an edge under the path)"
            )
            return est
    jack = _line_jackknife_deg(t, x, h, est.baseline_m)
    walk = _deg_se(fit.gradient, walk_gradient_se(t, x, fit.weights, st.height_walk_m))
    stat = max(jack, math.hypot(_deg_se(fit.gradient, fit.gradient_se), walk))
    att = math.sin(math.radians(slope)) ** 2 * st.attitude_error_deg
    est.sigma_deg = max(st.sigma_floor_deg, math.hypot(stat, att))
    if est.sigma_deg > st.max_sigma_deg:
        est.refusal = (
            f"too uncertain: {slope:.1f} +/- {est.sigma_deg:.1f} deg (at most {st.max_sigma_deg:g} deg)"
        )
    return est


@dataclass(frozen=True)
class PlaneFit:
    """``h = intercept + gn dn + ge de`` (h up; dn, de north and east of the spot); ``weights``
    per point (0..1), ``scale_m`` the residuals' robust scale, ``cov`` the 2x2 covariance of
    (gn, ge) from the weighted fit and ``rows`` the two rows of the fit that give (gn, ge) as
    weighted sums of the heights (for the height wander's share)."""

    intercept: float
    gradient: tuple[float, float]
    weights: np.ndarray
    scale_m: float
    cov: np.ndarray
    rows: np.ndarray


def _wls(a: np.ndarray, h: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The weighted least-squares coefficients (rank-deficient designs: the minimum norm)."""
    sw = np.sqrt(w)
    return np.linalg.lstsq(a * sw[:, None], h * sw, rcond=None)[0]


def fit_plane(
    dn: np.ndarray, de: np.ndarray, h: np.ndarray, groups: np.ndarray | None = None, iterations: int = 30
) -> PlaneFit:
    """Robust ``h = a_k + gn dn + ge de``: one plane, an intercept ``a_k`` per group of points
    (``groups``, labels 0..; None: one group) so that the legs of a pass flown at different times
    may sit at different heights (the position's height wanders; both legs cross the spot, so the
    gradients are each leg's own), a least-absolute-deviations start (a plane that a quarter of the
    heights being wrong does not move: the points of a pass lie in a bounded patch, so no point
    pulls by its position), then IRLS with Tukey's biweight on the MAD scale of the residuals
    (re-estimated each round, floored at :data:`SCALE_FLOOR_M`). ``intercept``: the first group's."""
    dn, de, h = (np.asarray(v, float) for v in (dn, de, h))
    if h.size < 3:
        raise ValueError("a plane needs at least three points")
    labels = np.zeros(h.size, int) if groups is None else np.asarray(groups, int)
    ones = [(labels == k).astype(float) for k in np.unique(labels)]
    a = np.column_stack([*ones, dn, de])
    beta = _wls(a, h, np.ones_like(h))
    for _ in range(50):  # L1 by reweighting: weights 1/|r|, held off zero
        r = np.abs(h - a @ beta)
        nb = _wls(a, h, 1.0 / np.maximum(r, 0.1 * SCALE_FLOOR_M))
        done = float(np.max(np.abs(nb - beta))) < 1e-9
        beta = nb
        if done:
            break
    w = np.ones_like(h)
    s = SCALE_FLOOR_M
    for _ in range(iterations):
        r = h - a @ beta
        s = max(SCALE_FLOOR_M, MAD_NORMAL * float(np.median(np.abs(r - np.median(r)))))
        u = r / (TUKEY_C * s)
        w = np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)
        if np.count_nonzero(w) < 3:
            break
        nb = _wls(a, h, w)
        done = float(np.max(np.abs(nb - beta))) < 1e-9
        beta = nb
        if done:
            break
    r = h - a @ beta
    sw = float(w.sum())
    normal = (a * w[:, None]).T @ a
    try:
        inv = np.linalg.inv(normal)
    except np.linalg.LinAlgError:
        inv = np.full(normal.shape, np.inf)
    neff = float(np.count_nonzero(w > OUTLIER_WEIGHT))
    var = float((w * r * r).sum() / max(1.0, sw)) * neff / max(1.0, neff - a.shape[1])
    cov = max(var, SCALE_FLOOR_M**2) * inv[-2:, -2:]
    rows = (inv @ (a * w[:, None]).T)[-2:] if np.all(np.isfinite(inv)) else np.full((2, h.size), np.inf)
    return PlaneFit(float(beta[0]), (float(beta[-2]), float(beta[-1])), w, s, cov, rows)


def walk_gradient_cov(t: np.ndarray, rows: np.ndarray, walk: float) -> np.ndarray:
    """:func:`walk_gradient_se` for a plane: the 2x2 covariance of (gn, ge) = ``rows @ h`` from a
    height error that is a random walk of ``walk`` m per sqrt(s). Each row sums to zero (the
    intercepts take a common offset), so the covariance is ``walk^2`` times the integral over time
    of ``S_a(s) S_b(s)``, ``S`` the sums of each row's entries after ``s``."""
    if walk <= 0:
        return np.zeros((2, 2))
    if not np.all(np.isfinite(rows)):
        return np.full((2, 2), np.inf)
    order = np.argsort(t, kind="stable")
    c = rows[:, order]
    after = np.cumsum(c[:, ::-1], axis=1)[:, ::-1][:, 1:]
    gaps = np.diff(t[order])
    return walk * walk * (after * gaps) @ after.T


def _unit(azimuth_deg: float) -> np.ndarray:
    a = math.radians(azimuth_deg)
    return np.array([math.cos(a), math.sin(a)])


def _leg_labels(t: np.ndarray, legs: list[np.ndarray]) -> np.ndarray:
    """Which leg each point was seen on: the direction it lies along from the spot (``legs``: a mask
    per direction, of the points clear of the spot), or, near the spot (on both or neither), the
    leg of the nearest point in time that has one; legs flown twice
    (out, elsewhere, back) are one leg each time: a label per run of consecutive points."""
    order = np.argsort(t, kind="stable")
    own = np.full(t.size, -1)
    for k, m in enumerate(legs):
        own[m & (own == -1)] = k
    own[legs[0] & legs[1]] = -1
    seq = own[order]
    known = np.flatnonzero(seq >= 0)
    if known.size == 0:
        return np.zeros(t.size, int)
    nearest = known[np.clip(np.searchsorted(known, np.arange(seq.size)), 0, known.size - 1)]
    before = known[np.clip(np.searchsorted(known, np.arange(seq.size)) - 1, 0, known.size - 1)]
    pick = np.where(
        np.abs(before - np.arange(seq.size)) < np.abs(nearest - np.arange(seq.size)), before, nearest
    )
    seq = seq[pick]
    runs = np.concatenate([[0], np.cumsum(seq[1:] != seq[:-1])])
    out = np.empty(t.size, int)
    out[order] = runs
    return out


def _directions(dn: np.ndarray, de: np.ndarray, st: EstimateSettings) -> list[float]:
    """The one or two directions (deg, 0..180) the points around the spot lie along (a pass's
    legs): the most populated 5-deg bin of the bearings from the spot (mod 180) of the points at
    least :data:`LEG_BAND_M` away, then the most populated one at least
    :data:`SECOND_DIRECTION_DEG` from it; each then refined to the principal axis of the points
    in its band (within :data:`LEG_BAND_M` of the line through the spot along it, clear of the
    spot), since a leg flown beside the spot skews the bearings near it. A direction seen by fewer
    than a quarter of ``min_points`` points is not one."""
    xy = np.column_stack([dn, de])
    far = np.hypot(dn, de) >= LEG_BAND_M
    if np.count_nonzero(far) < 5:
        return []
    bearing = np.degrees(np.arctan2(de[far], dn[far])) % 180.0
    counts = np.bincount((bearing // 5.0).astype(int) % 36, minlength=36)
    smooth = counts + np.roll(counts, 1) + np.roll(counts, -1)
    need = max(5, st.min_points // 4)
    out: list[float] = []
    for _ in range(2):
        if out:
            gap = np.abs((np.arange(36) * 5.0 + 2.5 - out[0] + 90.0) % 180.0 - 90.0)
            smooth = np.where(gap >= SECOND_DIRECTION_DEG, smooth, 0)
        i = int(np.argmax(smooth))
        if smooth[i] < need:
            break
        d = i * 5.0 + 2.5
        for _ in range(3):
            band = (np.abs(xy @ _unit(d + 90.0)) <= LEG_BAND_M) & (np.abs(xy @ _unit(d)) >= LEG_BAND_M)
            if np.count_nonzero(band) < 5:
                break
            c = xy[band] - xy[band].mean(axis=0)
            axis = np.linalg.eigh(c.T @ c)[1][:, 1]
            d = math.degrees(math.atan2(float(axis[1]), float(axis[0]))) % 180.0
        out.append(float(d))
    return out


@dataclass
class PlaneEstimate:
    """The plane under the spot from :func:`estimate_plane`: its gradient (dh/dnorth, dh/deast),
    the gradient's covariances (the weighted fit's own with the height's wander, and the block
    jackknife's: a direction's variance is the larger of the two), or why it is refused."""

    refusal: str | None
    spot_ne: tuple[float, float]
    settings: EstimateSettings
    gradient: tuple[float, float] | None = None
    cov_fit: np.ndarray | None = None
    cov_jack: np.ndarray | None = None
    n_points: int = 0
    n_inliers: int = 0
    extents_m: tuple[float, float] = (0.0, 0.0)
    scale_m: float | None = None
    sides_deg: tuple[float, float] | None = None
    #: (t, north m, east m, height up m, weight) of every point fitted
    points: list[tuple[float, float, float, float, float]] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.refusal is None

    @property
    def needs_survey(self) -> bool:
        return self.refusal is not None and self.refusal.startswith(LACK)

    @property
    def fall_azimuth_deg(self) -> float | None:
        """Where the surface falls steepest (deg from north, clockwise); None without a gradient."""
        if self.gradient is None:
            return None
        gn, ge = self.gradient
        if gn == 0.0 and ge == 0.0:
            return 0.0
        return math.degrees(math.atan2(-ge, -gn)) % 360.0

    @property
    def plane_slope_deg(self) -> float | None:
        return None if self.gradient is None else math.degrees(math.atan(math.hypot(*self.gradient)))

    def gradient_along(self, azimuth_deg: float) -> tuple[float, float]:
        """The height's gradient along ``azimuth_deg`` and its standard error."""
        u = _unit(azimuth_deg)
        g = float(np.dot(self.gradient, u))
        var = max(float(u @ self.cov_fit @ u), float(u @ self.cov_jack @ u))
        return g, math.sqrt(var) if var >= 0 else math.inf

    def slope_along(self, azimuth_deg: float) -> tuple[float, float]:
        """The slope (deg, positive falling toward ``azimuth_deg``) and its 1 sigma: the
        statistical error, the attitude's bias (sin^2 of the plane's slope of
        ``attitude_error_deg``) and the floor, as :func:`estimate` has them."""
        st = self.settings
        g, se = self.gradient_along(azimuth_deg)
        stat = _deg_se(g, se)
        att = math.sin(math.radians(self.plane_slope_deg)) ** 2 * st.attitude_error_deg
        return _deg(g), max(st.sigma_floor_deg, math.hypot(stat, att))

    def fall_azimuth_sigma_deg(self) -> float:
        """1 sigma of the fall line's azimuth: the gradient's error across it over its length."""
        g = math.hypot(*self.gradient)
        if g <= 0:
            return 180.0
        _, se = self.gradient_along(self.fall_azimuth_deg + 90.0)
        return min(180.0, math.degrees(se / g))

    def along(self, heading_deg: float) -> SlopeEstimate:
        """The estimate along the vehicle's heading (deg from north): the slope along it (the
        planar model's x), the cross-slope (to its right), the plane's slope and fall line, and the
        points as a section along the heading; refused when the plane was, or when the slope along
        the heading is too uncertain (``max_sigma_deg``)."""
        st = self.settings
        u = _unit(heading_deg)
        v = _unit(heading_deg + 90.0)
        spot_n, spot_e = self.spot_ne
        est = SlopeEstimate(
            None,
            None,
            self.refusal,
            float(spot_n * u[0] + spot_e * u[1]),
            n_points=self.n_points,
            n_inliers=self.n_inliers,
            baseline_m=float(min(self.extents_m)),
            scale_m=self.scale_m,
            sides_deg=self.sides_deg,
            heading_deg=heading_deg % 360.0,
            spot_ne_m=self.spot_ne,
        )
        g_cross = float(np.dot(self.gradient, v)) if self.gradient is not None else 0.0
        est.points = [
            (
                t,
                float(n * u[0] + e * u[1]),
                float(h - g_cross * ((n - spot_n) * v[0] + (e - spot_e) * v[1])),
                w,
            )
            for t, n, e, h, w in self.points
        ]
        if self.gradient is None:
            return est
        est.slope_deg, est.sigma_deg = self.slope_along(heading_deg)
        est.cross_deg, est.cross_sigma_deg = self.slope_along(heading_deg + 90.0)
        est.plane_slope_deg = self.plane_slope_deg
        est.fall_azimuth_deg = self.fall_azimuth_deg
        est.plane_sigma_deg = self.slope_along(est.fall_azimuth_deg)[1]
        est.fall_azimuth_sigma_deg = self.fall_azimuth_sigma_deg()
        if est.ok and est.sigma_deg > st.max_sigma_deg:
            est.refusal = (
                f"too uncertain: {est.slope_deg:.1f} +/- {est.sigma_deg:.1f} deg along heading "
                f"{heading_deg % 360.0:.0f} deg (at most {st.max_sigma_deg:g} deg)"
            )
        return est


def _coverage_refusal(
    dirs: list[float],
    proj: list[np.ndarray],
    legs: list[np.ndarray],
    extents: tuple[float, ...],
    st: EstimateSettings,
) -> str | None:
    """Why the points do not see enough of the surface along each direction (the baseline, and
    both sides of the spot), or None."""
    for d, p, m, ext in zip(dirs, proj, legs, extents, strict=True):
        if ext < st.min_baseline_m:
            return (
                f"{LACK}: the points span {ext:.2f} m along {d:.0f} deg ({st.min_baseline_m:g} m needed "
                "two ways: the slope across the pass is unseen)"
            )
        behind, ahead = -float(p[m].min()), float(p[m].max())
        if min(behind, ahead) < st.min_side_m:
            toward = d if ahead < behind else d + 180.0
            return (
                f"{LACK}: surface seen only {min(behind, ahead):.2f} m toward {az_text(toward)} of the spot "
                f"({st.min_side_m:g} m needed; an edge or a gutter there?)"
            )
    return None


def _own_runs(legs: list[np.ndarray], far: np.ndarray, groups: np.ndarray) -> list[np.ndarray]:
    """Each leg's own points: the run of its own clear of the crossing, with its stretch near the
    spot (a slow height wander offsets one leg from the other, so each side is fitted from one)."""
    own = []
    for k, m in enumerate(legs):
        clear = m & far & ~legs[1 - k]
        label = np.bincount(groups[clear]).argmax() if clear.any() else -1
        own.append(m & (groups == label))
    return own


def _side_slopes(
    t: np.ndarray, p: np.ndarray, h: np.ndarray, sides: tuple[np.ndarray, np.ndarray], st: EstimateSettings
) -> list[tuple[float, float]]:
    """The slope (deg) and its standard error of the heights ``h`` (read at ``t``) along ``p``
    before and beyond the spot (the two masks ``sides``), for each side seen well enough to fit a
    line. The error is the fit's own with the height's slow wander, as the whole estimate's: a
    side is half the baseline, so the wander tilts it more (on ArduCopter SITL's 35 deg roof the
    two sides of a leg differed by up to 5.2 deg where the fit alone allowed 4.3)."""
    out = []
    for side in sides:
        if np.count_nonzero(side) >= max(5, st.min_points // 4) and np.ptp(p[side]) >= 0.5 * st.min_side_m:
            f = fit_line(p[side], h[side])
            walk = walk_gradient_se(t[side], p[side], f.weights, st.height_walk_m)
            out.append((_deg(f.gradient), _deg_se(f.gradient, math.hypot(f.gradient_se, walk))))
    return out


def _one_plane_refusal(
    est: PlaneEstimate,
    dirs: list[float],
    axes: list[np.ndarray],
    proj: list[np.ndarray],
    own: list[np.ndarray],
    xy: np.ndarray,
    t: np.ndarray,
    h: np.ndarray,
) -> str | None:
    """Why the two sides of the spot are not one plane along some direction (a ridge or an edge
    under the path), or None; keeps in ``est.sides_deg`` the two sides that differ most."""
    g = np.array(est.gradient)
    for d, ax, p, m in zip(dirs, axes, proj, own, strict=True):
        across = np.array([-ax[1], ax[0]])
        hh = h - float(g @ across) * (xy @ across)  # the heights less the slope across
        sides = _side_slopes(t, p, hh, (m & (p < 0), m & (p >= 0)), est.settings)
        if len(sides) != 2:
            continue
        diff = abs(sides[0][0] - sides[1][0])
        allowed = 3.0 * math.hypot(sides[0][1], sides[1][1]) + est.settings.plane_tolerance_deg
        if est.sides_deg is None or diff > abs(est.sides_deg[0] - est.sides_deg[1]):
            est.sides_deg = (sides[0][0], sides[1][0])
        if diff > allowed:
            return (
                f"the surface is not one plane: toward {az_text(d)} it falls "
                f"{sides[0][0]:.1f} deg before the spot and {sides[1][0]:.1f} deg beyond it "
                "(a ridge or an edge under the path)"
            )
    return None


def _jackknife_cov(
    t: np.ndarray,
    ne: tuple[np.ndarray, np.ndarray],
    h: np.ndarray,
    groups: np.ndarray,
    proj: list[np.ndarray],
    legs: list[np.ndarray],
    extents: tuple[float, ...],
) -> np.ndarray | None:
    """The gradient's covariance from the block jackknife in time order, leaving out each block
    that still leaves every leg a quarter of its extent; None with fewer than 3 such fits."""
    dn, de = ne
    order = np.argsort(t)
    leave = []
    for b in np.array_split(order, JACKKNIFE_BLOCKS):
        keep = np.ones(t.size, bool)
        keep[b] = False
        if keep.sum() >= 3 and all(
            np.ptp(p[keep & m]) > 0.25 * ext
            for p, m, ext in zip(proj, legs, extents, strict=True)
            if (keep & m).any()
        ):
            leave.append(fit_plane(dn[keep], de[keep], h[keep], groups[keep]).gradient)
    k = len(leave)
    if k < 3:
        return None
    d = np.array(leave) - np.mean(leave, axis=0)
    return (k - 1) / k * (d.T @ d)


def estimate_plane(
    points: list[tuple[float, float, float, float]],
    spot_ne: tuple[float, float],
    settings: EstimateSettings | None = None,
) -> PlaneEstimate:
    """The plane at the landing spot (north, east) from ``points`` (t, north, east, height up)
    within ``half_span_m`` of it, or a refusal saying why not. What :func:`estimate` asks of a line
    it asks of the plane along both of the points' principal directions (a pass flown one way only
    sees one gradient: too little seen), and its uncertainty has the same parts, as covariances of
    the two gradients: the weighted fit's own with the height's slow wander
    (:func:`walk_gradient_cov`), and the block jackknife over :data:`JACKKNIFE_BLOCKS` runs of
    consecutive points; a direction's variance is the larger of the two."""
    st = settings or EstimateSettings()
    sn, se_ = spot_ne
    near = [p for p in points if math.hypot(p[1] - sn, p[2] - se_) <= st.half_span_m]
    est = PlaneEstimate(None, (float(sn), float(se_)), st, n_points=len(near))
    if not near:
        est.refusal = f"{LACK}: no rangefinder point within {st.half_span_m:g} m of the spot"
        return est
    arr = np.array(near, float)
    t, dn, de, h = arr[:, 0], arr[:, 1] - sn, arr[:, 2] - se_, arr[:, 3]
    est.points = [(float(a), float(b), float(c), float(d), 1.0) for a, b, c, d in near]
    if len(near) < st.min_points:
        est.refusal = f"{LACK}: {len(near)} points, {st.min_points} needed"
        return est
    # the directions the points were seen along (a survey pass: its two legs), the most seen first
    xy = np.column_stack([dn, de])
    dirs = _directions(dn, de, st)
    if len(dirs) < 2:
        along = f"along {dirs[0]:.0f} deg only" if dirs else "around the spot only"
        est.refusal = (
            f"{LACK}: the points lie {along}: the slope across is unseen "
            f"({st.min_baseline_m:g} m needed two ways)"
        )
        return est
    axes = [_unit(d) for d in dirs]
    proj = [xy @ ax for ax in axes]
    legs = [np.abs(xy @ _unit(d + 90.0)) <= LEG_BAND_M for d in dirs]
    est.extents_m = tuple(float(np.ptp(p[m])) for p, m in zip(proj, legs, strict=True))
    est.refusal = _coverage_refusal(dirs, proj, legs, est.extents_m, st)
    if est.refusal is not None:
        return est
    far = np.hypot(dn, de) >= max(0.1, 0.5 * st.min_side_m)
    groups = _leg_labels(t, [m & far for m in legs])
    fit = fit_plane(dn, de, h, groups)
    est.points = [
        (float(a), float(b), float(c), float(d), float(w))
        for (a, b, c, d), w in zip(near, fit.weights, strict=True)
    ]
    est.scale_m = fit.scale_m
    est.n_inliers = int(np.count_nonzero(fit.weights > OUTLIER_WEIGHT))
    est.gradient = fit.gradient
    est.cov_fit = fit.cov + walk_gradient_cov(t, fit.rows, st.height_walk_m)
    est.cov_jack = np.full((2, 2), np.inf)
    frac = est.n_inliers / len(near)
    if frac < st.min_inlier_fraction:
        est.refusal = (
            f"only {frac:.0%} of {len(near)} points lie on one plane "
            f"({st.min_inlier_fraction:.0%} needed): the surface under the pass is not flat"
        )
        return est
    # the two sides of the spot along each direction, from that leg's points alone: one plane has
    # one slope there
    est.refusal = _one_plane_refusal(est, dirs, axes, proj, _own_runs(legs, far, groups), xy, t, h)
    if est.refusal is not None:
        return est
    cov = _jackknife_cov(t, (dn, de), h, groups, proj, legs, est.extents_m)
    if cov is not None:
        est.cov_jack = cov
    return est


def check_bound(cell_deg: float, sigma_deg: float, sigmas: float, fixed_deg: float | None = None) -> float:
    """How far a pilot's slope may lie from the measured one (deg): ``fixed_deg`` when set, else
    half the table's slope cell (a slope within it picks a neighbouring cell's preset at worst)
    plus ``sigmas`` of the estimate's uncertainty."""
    if fixed_deg is not None:
        return float(fixed_deg)
    return 0.5 * cell_deg + sigmas * sigma_deg


def slope_to_land(est: SlopeEstimate, bound_deg: float) -> tuple[float | None, str | None]:
    """The slope (deg, >= 0) a landing may use from ``est``, or why none: a surface falling toward
    the vehicle's back (south, without a heading) by more than ``bound_deg`` has the vehicle facing
    uphill (its uphill legs downhill)."""
    if not est.ok:
        return None, est.describe()
    if est.slope_deg < -bound_deg:
        back = compass((est.heading_deg or 0.0) + 180.0)
        where = back if est.heading_deg is None else f"the vehicle's back ({back})"
        return None, (
            f"the surface falls toward {where} ({-est.slope_deg:.1f} deg): the vehicle must face "
            f"downhill ({compass(est.fall_azimuth_deg if est.fall_azimuth_deg is not None else 0.0)}) to land"
        )
    return max(0.0, est.slope_deg), None


def pilot_refusal(pilot_deg: float, est: SlopeEstimate, bound_deg: float) -> str | None:
    """Why the pilot's slope does not fit the measured one (along the vehicle's heading, when the
    estimate has one), naming both, or None."""
    if not est.ok:
        return est.describe()
    if abs(pilot_deg - est.slope_deg) > bound_deg:
        along = f" along heading {round(est.heading_deg) % 360} deg" if est.heading_deg is not None else ""
        return (
            f"pilot's slope {pilot_deg:g} deg, measured {est.slope_deg:.1f} +/- {est.sigma_deg:.1f} deg"
            f"{along} (they may differ by {bound_deg:.1f} deg)"
        )
    return None


def cross_refusal(est: SlopeEstimate, max_cross_deg: float) -> str | None:
    """Why a landing on ``est`` is refused for the slope across the vehicle's heading (the legs'
    plane and the lookup table know none), naming the plane, the heading and the way to face, or
    None."""
    if not est.ok or est.cross_deg is None or abs(est.cross_deg) <= max_cross_deg:
        return None
    return (
        f"{est.plane_text()}: more than {max_cross_deg:g} deg across; "
        f"face {az_text(est.fall_azimuth_deg)} to land"
    )
