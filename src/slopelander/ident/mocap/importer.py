"""Raw takes to a dataset: read and check every take, then solve each, then write them all.

Order matters to a user: every file, marker name, unit and the cluster's rigidity is checked
for every take before any take is solved, and nothing appears in the output folder until all
takes are done (they are written to a hidden folder beside it, which is then renamed).
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from slopelander.ident.mocap import rates as rate_filter
from slopelander.ident.mocap.contact import (
    GRAVITY,
    MIN_FLIGHT,
    Contact,
    Flight,
    FootContact,
    contact_time,
    find_flight,
    flight_residual,
    flight_state,
    foot_contact,
)
from slopelander.ident.mocap.formats import read_take
from slopelander.ident.mocap.markerset import MarkerSet, load_markerset
from slopelander.ident.mocap.plane import axis_vector, fit_plane, landing_frame
from slopelander.ident.mocap.pose import check_rigid, fit_cluster
from slopelander.ident.mocap.take import MocapError, Take
from slopelander.ident.recording import Drop, write_drop
from slopelander.model import ConditionError, LandingConditions, Outcome

TAKE_SUFFIXES = (".c3d", ".csv", ".tsv")
UP_TOLERANCE_DEG = 30.0
"""deg: how far the free fall may point from the declared vertical axis (axes are 90 apart)."""
ROOF_FLATNESS = 0.005
"""m: RMS distance of the roof markers from their plane above which they are not one plane."""
MAX_HEIGHT = 20.0
"""m: a body higher than this above the roof is a unit mistake, not a drop."""
MIN_AFTER = 0.1
"""s of recording after contact a take needs."""
MAX_GAPS = 0.5
"""Share of frames after contact that may be gaps."""


@dataclass(frozen=True)
class Checked:
    """A take read and checked, ready to solve."""

    take: Take
    body_idx: list[int]
    roof_idx: list[int]
    entry: dict[str, Any]
    feet_idx: tuple[int, ...] = ()


@dataclass(frozen=True)
class Imported:
    drop: Drop
    planar: bool
    lines: tuple[str, str]
    """What ``slopelander import`` prints for it: the impact, and the data-quality line."""


def take_files(paths: list[Path], skip: Path | None = None) -> list[Path]:
    """The take files named, a folder standing for every take file in it (sorted), less
    ``skip`` (the markers file's table of takes)."""
    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            found = sorted(
                q
                for q in p.iterdir()
                if q.suffix.lower() in TAKE_SUFFIXES
                and q.is_file()
                and not (skip and q.resolve() == skip.resolve())
            )
            if not found:
                raise MocapError(p, None, "<folder>", "holds no take (*.c3d, *.csv, *.tsv)")
            out += found
        else:
            out.append(p)
    names = [drop_name(p) for p in out]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise MocapError(
            out[names.index(sorted(dup)[0])],
            None,
            "<name>",
            f"two takes would both be drop '{sorted(dup)[0]}'",
        )
    return out


def drop_name(path: Path) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", path.stem)


def check_take(path: Path, ms: MarkerSet) -> Checked:
    """Read one take and check what can be checked without solving it: the markers are there,
    the lengths can be in the file's unit, the cluster is the declared rigid shape."""
    take = read_take(path)
    entry = ms.take_entry(path)
    body_idx: list[int] = []
    if ms.rigid_body is not None:
        if ms.rigid_body.name in take.unusable:
            raise MocapError(path, take.name, "body.rigid_body", take.unusable[ms.rigid_body.name])
        if ms.rigid_body.name not in take.bodies:
            have = ", ".join(take.bodies) or "none"
            raise MocapError(
                path,
                take.name,
                "body.rigid_body",
                f"no rigid body '{ms.rigid_body.name}' (the take has {have})",
            )
    else:
        body_idx = [take.index(m, f"body.markers.{m}") for m in ms.body]
    roof_idx = [take.index(m, f"roof.markers.{m}") for m in ms.roof]
    feet_idx = [take.index(m, f"feet.markers.{m}") for m in ms.feet]
    _check_extent(take, body_idx + roof_idx + feet_idx)
    if body_idx:
        check_rigid(
            take.xyz[:, body_idx],
            np.array(list(ms.body.values())),
            list(ms.body),
            ms.rigid_tolerance,
            (str(path), take.name, "body.markers"),
        )
    for i, m in zip(roof_idx, ms.roof, strict=True):
        if np.isfinite(take.xyz[:, i, 0]).sum() < 3:
            raise MocapError(path, take.name, f"roof.markers.{m}", "seen in fewer than 3 frames")
    if take.up and ms.up_axis and take.up != ms.up_axis:
        raise MocapError(
            path,
            take.name,
            take.up_field,
            f"the file says the vertical is {take.up}, the markers file's up_axis {ms.up_axis}",
        )
    return Checked(take, body_idx, roof_idx, entry, tuple(feet_idx))


def _check_extent(take: Take, idx: list[int]) -> None:
    """Refuse lengths that cannot be in the unit the file says: markers spread over kilometres."""
    pts = take.xyz[:, idx]
    if not np.isfinite(pts).any():
        return
    extent = float(np.nanmax(np.nanmax(pts, axis=(0, 1)) - np.nanmin(pts, axis=(0, 1))))
    if extent > 10 * MAX_HEIGHT:
        raise MocapError(
            take.path,
            take.name,
            take.units.split(" ")[0],
            f"the markers span {extent:.4g} m ({take.units}): the lengths are not in that unit",
        )


def _pose(c: Checked, ms: MarkerSet) -> tuple[np.ndarray, np.ndarray, float | None, list[str]]:
    """Body-to-capture rotations, centre-of-mass positions, the marker jitter (None for a
    solved rigid body) and the markers used."""
    take = c.take
    if ms.rigid_body is None:
        body = np.array(list(ms.body.values()))
        fit = fit_cluster(take.xyz[:, c.body_idx], body)
        return fit.rotation, fit.position, fit.marker_sd, [take.labels[i] for i in c.body_idx]
    from scipy.spatial.transform import Rotation

    rb = take.bodies[ms.rigid_body.name]
    n = take.frames
    rot = np.full((n, 3, 3), np.nan)
    ok = np.isfinite(rb.quaternion).all(axis=1) & np.isfinite(rb.position).all(axis=1)
    fwd, upv = axis_vector(ms.rigid_body.forward), axis_vector(ms.rigid_body.up)
    local = np.column_stack([fwd, np.cross(upv, fwd), upv])  # body axes in the rigid body's frame
    if ok.any():
        rot[ok] = Rotation.from_quat(rb.quaternion[ok]).as_matrix() @ local
    pos = rb.position + np.einsum(
        "fij,j->fi", np.where(ok[:, None, None], rot, np.nan), local.T @ ms.rigid_body.centre_of_mass
    )
    return rot, pos, None, [f"rigid body {ms.rigid_body.name}"]


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, length) of each run of True."""
    d = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return [
        (int(s), int(e - s)) for s, e in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True)
    ]


def _pose_noise(take: Take, ms: MarkerSet, marker_sd: float | None) -> tuple[float, float, float]:
    """Position and angle noise of the pose (nan until the free flight gives them, for a solved
    rigid body), and the jitter the free-fall search must allow for."""
    if ms.rigid_body is None:  # a marker cluster: its fit measured the jitter (marker_sd)
        r = np.array(list(ms.body.values()))
        rc = r - r.mean(axis=0)
        pos_sd = marker_sd / math.sqrt(len(r))
        ang_sd = marker_sd / math.sqrt(float((rc[:, 0] ** 2 + rc[:, 2] ** 2).sum()))
        return pos_sd, ang_sd, pos_sd
    errs = take.bodies[ms.rigid_body.name].error
    noise_for_flight = float(np.nanmedian(errs)) / 1.6 if np.isfinite(errs).any() else 5e-4
    return math.nan, math.nan, noise_for_flight


def _free_fall(take: Take, t: np.ndarray, pos: np.ndarray, noise: float) -> tuple[Flight, float]:
    """The free fall that opens the take and its measured acceleration (m/s^2), refused when
    the pose is too rarely found, or the fall is missing or says the lengths are in another unit."""
    path = take.path
    seen = np.isfinite(pos[:, 0])
    if seen.sum() < MIN_FLIGHT + 2:
        raise MocapError(
            path, take.name, "body", f"the body's pose is found in only {int(seen.sum())} frames"
        )
    flight = find_flight(t, pos, noise)
    if flight is None:
        raise MocapError(
            path,
            take.name,
            "<contact>",
            f"no first contact found: the take must start with at least {MIN_FLIGHT} frames of free fall "
            "and the body must then be stopped by the roof",
        )
    g_meas = float(np.linalg.norm(flight.accel))
    if not GRAVITY / 4 <= g_meas <= GRAVITY * 4:
        raise MocapError(
            path,
            take.name,
            take.units.split(" ")[0],
            f"the free fall measures {g_meas:.4g} m/s^2, not {GRAVITY} ({take.units}): the lengths are not "
            f"in that unit (a factor {g_meas / GRAVITY:.3g} off)",
        )
    if not 0.65 * GRAVITY <= g_meas <= 1.35 * GRAVITY:
        raise MocapError(
            path,
            take.name,
            "<contact>",
            f"the take does not start in free fall: its first {flight.frames} frames accelerate at "
            f"{g_meas:.3g} m/s^2 (gravity {GRAVITY}); it must start {MIN_FLIGHT} frames or more "
            "before contact",
        )
    return flight, g_meas


def _vertical(take: Take, ms: MarkerSet, flight: Flight, g_meas: float) -> tuple[np.ndarray, str]:
    """The up unit vector and how it was known: the declared axis checked against the free fall,
    or, when none is declared, the axis the free fall points along."""
    down = flight.accel / g_meas
    declared, fieldname = (take.up, take.up_field) if take.up else (ms.up_axis, "up_axis")
    if declared:
        up = axis_vector(declared)
        off = math.degrees(math.acos(float(np.clip(-down @ up, -1, 1))))
        if off > UP_TOLERANCE_DEG:
            raise MocapError(
                take.path,
                take.name,
                fieldname,
                f"the first {flight.frames} frames accelerate {off:.0f} deg away from the vertical "
                f"{declared}: the take does not start in free fall, or the vertical is wrong",
            )
        return up, f"{declared} ({fieldname})"
    k = int(np.argmax(np.abs(down)))
    up = np.zeros(3)
    up[k] = -math.copysign(1.0, down[k])
    off = math.degrees(math.acos(float(np.clip(-down @ up, -1, 1))))
    declared = ("+" if up[k] > 0 else "-") + "XYZ"[k]
    if off > UP_TOLERANCE_DEG:
        raise MocapError(
            take.path, take.name, "up_axis", f"the free fall is {off:.0f} deg from every axis: give up_axis"
        )
    return up, f"{declared} (measured: the free fall, {off:.1f} deg off)"


def _roof_plane(c: Checked, ms: MarkerSet, up: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A point on the roof's surface, its normal, and the markers' RMS distance from their plane
    (0 for a plane the markers file gives), refused when the markers are not one plane."""
    if ms.plane is not None:
        p0, normal = ms.plane
        return p0, normal, 0.0
    take = c.take
    roof_pts = np.nanmean(take.xyz[:, c.roof_idx], axis=0)
    p0, normal, roof_rms = fit_plane(roof_pts)
    p0 = p0 - ms.roof_height * (normal if normal @ up > 0 else -normal)  # markers sit on the surface
    if roof_rms > ROOF_FLATNESS:
        raise MocapError(
            take.path,
            take.name,
            "roof.markers",
            f"the roof markers are {1000 * roof_rms:.1f} mm (RMS) off one plane",
        )
    return p0, normal, roof_rms


def _foot_contact(
    c: Checked,
    ms: MarkerSet,
    t: np.ndarray,
    up: np.ndarray,
    roof: tuple[np.ndarray, np.ndarray],
    jitter: float,
    body_contact: Contact,
) -> FootContact:
    """First contact from the foot markers, refused when no foot is seen reaching the roof or
    when it disagrees with the body's deceleration (a wrong marker height)."""
    take = c.take
    p0, normal = roof
    n_up = normal if normal @ up > 0 else -normal
    heights = (take.xyz[:, list(c.feet_idx)] - p0) @ n_up - ms.foot_height
    fc = foot_contact(t, heights, GRAVITY * float(up @ n_up), jitter)
    if fc is None:
        raise MocapError(
            take.path,
            take.name,
            "feet.markers",
            "no foot marker is seen in 3 frames of free flight before it reaches the roof",
        )
    if abs(fc.time - body_contact.time) > 0.02:
        raise MocapError(
            take.path,
            take.name,
            "feet.marker_height",
            f"{ms.feet[fc.foot]} reaches the roof at {fc.time:.4f} s, but the body decelerates from "
            f"{body_contact.time:.4f} s: is the marker height at touch ({1000 * ms.foot_height:g} mm) right?",
        )
    return fc


def _landing_attitude(
    rot: np.ndarray, in_flight: np.ndarray, normal: np.ndarray, up: np.ndarray
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, bool]:
    """The landing frame (rows x downhill, y out of the plane, z up), the slope (deg), the body's
    rotations and unwrapped pitch in it, and whether the body was turned to face downhill."""
    fwd = np.nanmean(rot[in_flight][:, :, 0], axis=0)
    frame, slope = landing_frame(normal, up, fwd)
    turned = False
    if fwd @ frame[0] < 0:  # the body's x faced uphill: the same planar vehicle turned about z
        rot = rot @ np.diag([-1.0, -1.0, 1.0])
        turned = True
    rm = np.einsum("ij,fjk->fik", frame, rot)
    pitch = np.arctan2(rm[:, 2, 0], rm[:, 0, 0])
    ok = np.isfinite(pitch)
    pitch[ok] = np.unwrap(pitch[ok])
    return frame, slope, rm, pitch, turned


def _height_at_contact(
    take: Take, pos_c: np.ndarray, roof: tuple[np.ndarray, np.ndarray], up: np.ndarray
) -> float:
    """Height (m) of the centre of mass over the roof, straight down, at contact; refused when
    it cannot be a landing (a unit mistake)."""
    p0, normal = roof
    height = float(normal @ (pos_c - p0) / (normal @ up)) if normal @ up != 0 else math.inf
    if not 0.0 < height < MAX_HEIGHT:
        raise MocapError(
            take.path,
            take.name,
            take.units.split(" ")[0],
            f"the body is {height:.4g} m above the roof at contact ({take.units}): not a landing",
        )
    return height


def _gap_share(take: Take, tk: np.ndarray, gaps: np.ndarray) -> float:
    """Share of the frames after contact that are gaps, refused when the take ends too soon
    after contact or is mostly gaps there."""
    if tk[-1] < MIN_AFTER:
        raise MocapError(
            take.path,
            take.name,
            "<data>",
            f"too little data: the take ends {tk[-1]:.3f} s after contact (need {MIN_AFTER} s)",
        )
    gap_share = float(gaps[tk >= 0].mean())
    if gap_share > MAX_GAPS:
        raise MocapError(
            take.path,
            take.name,
            "<data>",
            f"too little data: {100 * gap_share:.0f} % of the frames after contact are gaps",
        )
    return gap_share


def _conditions(c: Checked, measured: dict[str, float]) -> LandingConditions:
    """The landing's conditions: those measured from the take, with those the takes table gives,
    checked as the model checks them; a bad one is named by its field."""
    given = {k: v for k, v in c.entry.items() if k != "outcome"}
    try:
        cond = LandingConditions(**measured, **given)
        cond.validate(0.0, 37.5)
    except ConditionError as exc:
        raise MocapError(
            c.take.path, c.take.name, f"conditions.{exc.field}", str(exc).split(": ", 1)[-1]
        ) from None
    return cond


@dataclass(frozen=True)
class _OutOfPlane:
    """How far the body left the landing plane after contact, and the limits it went over."""

    lateral: float
    """m: the centre of mass's largest drift across the plane from its mean before contact."""
    yaw_deg: float
    roll_deg: float
    over: list[str]


def _out_of_plane(
    ms: MarkerSet, rm: np.ndarray, pitch: np.ndarray, q: np.ndarray, keep: np.ndarray, rel: np.ndarray
) -> _OutOfPlane:
    """The centre of mass's drift across the plane, the body's yaw and roll, against the markers
    file's limits: what decides whether a drop is planar."""
    from scipy.spatial.transform import Rotation

    okk = np.isfinite(rm[:, 0, 0]) & keep & (np.abs(pitch) < math.radians(75))
    yaw = roll = np.zeros(0)
    if okk.any():
        eul = Rotation.from_matrix(rm[okk]).as_euler("ZYX", degrees=True)
        yaw, roll = eul[:, 0], eul[:, 2]
    lateral = float(np.nanmax(np.abs(q[keep, 1] - np.nanmean(q[keep & (rel < 0), 1])))) if keep.any() else 0.0
    max_yaw = float(np.max(np.abs(yaw))) if yaw.size else 0.0
    max_roll = float(np.max(np.abs(roll))) if roll.size else 0.0
    over = []
    if lateral > ms.lateral_limit:
        over.append(f"lateral {1000 * lateral:.1f} mm > {1000 * ms.lateral_limit:.0f}")
    if max_yaw > ms.yaw_limit_deg:
        over.append(f"yaw {max_yaw:.1f} deg > {ms.yaw_limit_deg:g}")
    if max_roll > ms.roll_limit_deg:
        over.append(f"roll {max_roll:.1f} deg > {ms.roll_limit_deg:g}")
    return _OutOfPlane(lateral, max_yaw, max_roll, over)


def _gap_text(runs: list[tuple[int, int]], gaps: np.ndarray, dt: float, tk: np.ndarray) -> str:
    """The gaps as the data line prints them: how many, how long, the longest and where."""
    if not runs:
        return "none"
    return (
        f"{len(runs)} ({int(gaps.sum())} frames, longest {1000 * max(ln for _, ln in runs) * dt:.0f} ms at "
        f"{tk[max(runs, key=lambda r: r[1])[0]]:+.3f} s)"
    )


def _noise_meta(
    ms: MarkerSet,
    sd: tuple[float, float],
    fl_res: np.ndarray,
    marker_sd: float | None,
    markers: int,
) -> dict[str, Any]:
    """The drop's noise entry: position and angle noise, how they were measured, the latency."""
    pos_sd, ang_sd = sd
    return {
        "position_sd_m": round(pos_sd, 7),
        "angle_sd_deg": round(math.degrees(ang_sd), 5),
        "latency_s": ms.latency_s,
        "method": "rigid-fit residuals" if ms.rigid_body is None else "free-flight residuals",
        "flight_residual": {
            "x_m": round(float(fl_res[0]), 7),
            "z_m": round(float(fl_res[1]), 7),
            "pitch_deg": round(math.degrees(fl_res[2]), 5),
        },
        **({"marker_sd_m": round(marker_sd, 7), "markers": markers} if marker_sd is not None else {}),
    }


def _provenance(take: Take, ms: MarkerSet, up_note: str, used: list[str], turned: bool) -> dict[str, Any]:
    """The drop's provenance entry: the file and its hash, the take, and how its frame was found."""
    path = take.path
    return {
        "file": path.name,
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
        "take": take.name,
        "format": take.fmt,
        "units": take.units,
        "up": up_note,
        "markers_file": ms.path.name,
        "body": used,
        "roof": list(ms.roof) if ms.plane is None else "plane from the markers file",
        **({"turned": "the body's x faced uphill: turned 180 deg about its z"} if turned else {}),
    }


def _signed(v: float, digits: int) -> str:
    """A number with its sign, never "-0.00"."""
    return f"{round(v, digits) + 0.0:+.{digits}f}"


def _impact_line(name: str, cond: LandingConditions, ct: Contact, contact_from: str, by_feet: bool) -> str:
    """The first line ``slopelander import`` prints for a drop: the impact and the first contact."""
    return (
        f"{name}: slope {cond.slope_deg:.1f} deg, impact {cond.speed:.2f} m/s (horizontal "
        f"{_signed(cond.horizontal_speed, 2)} m/s, pitch {_signed(cond.pitch_deg, 1)} deg, "
        f"{_signed(cond.pitch_rate_dps, 0)} deg/s), "
        f"contact at {ct.time:.4f} s +- {1000 * ct.sd:.1f} ms" + (f" ({contact_from})" if by_feet else "")
    )


def _data_line(rate: float, tk: np.ndarray, gap_text: str, sd: tuple[float, float], oop: _OutOfPlane) -> str:
    """The second line ``slopelander import`` prints for a drop: the data's extent, gaps, noise
    and planarity."""
    pos_sd, ang_sd = sd
    return (
        f"  data: {rate:g} Hz, {len(tk)} frames ({-tk[0]:.2f} s before contact, "
        f"{tk[-1]:.2f} s after), "
        f"gaps {gap_text}, noise {1000 * pos_sd:.2f} mm / {math.degrees(ang_sd):.2f} deg, "
        + ("planar" if not oop.over else "NOT PLANAR")
        + f" (lateral {1000 * oop.lateral:.1f} mm, yaw {oop.yaw_deg:.1f} deg, roll {oop.roll_deg:.1f} deg"
        + (f": {'; '.join(oop.over)})" if oop.over else ")")
    )


def solve_take(c: Checked, ms: MarkerSet) -> Imported:
    """One take as a drop in the model's frame, with its provenance and data quality."""
    take, path = c.take, c.take.path
    rate = take.rate
    dt = 1.0 / rate
    t = np.arange(take.frames) * dt
    rot, pos, marker_sd, used = _pose(c, ms)
    pos_sd, ang_sd, noise_for_flight = _pose_noise(take, ms, marker_sd)
    flight, g_meas = _free_fall(take, t, pos, noise_for_flight)
    up, up_note = _vertical(take, ms, flight, g_meas)
    p0, normal, roof_rms = _roof_plane(c, ms, up)

    ct: Contact = contact_time(t, pos @ up, flight.onset, rate)
    contact_from = "the body's deceleration"
    if c.feet_idx:
        jitter = marker_sd if marker_sd is not None and math.isfinite(marker_sd) else noise_for_flight
        fc = _foot_contact(c, ms, t, up, (p0, normal), jitter, ct)
        ct, contact_from = fc, f"foot marker {ms.feet[fc.foot]}"
    tc = ct.time
    frame, slope, rm, pitch, turned = _landing_attitude(rot, t < tc, normal, up)

    pos_c, vel_c = flight_state(t, pos, tc, -GRAVITY * up)
    (pitch_c,), (prate_c,) = flight_state(t, pitch[:, None], tc, 0.0)
    height = _height_at_contact(take, pos_c, (p0, normal), up)
    origin = pos_c - height * up  # on the roof, straight below the centre of mass at contact
    q = (pos - origin) @ frame.T  # x downhill, y out of the plane, z up

    rel = t - tc
    keep = (rel >= -ms.before_s - 1e-9) & (rel <= ms.after_s + 1e-9)
    tk = rel[keep]
    states_pos = np.column_stack([q[keep, 0], q[keep, 2], pitch[keep]])
    gaps = ~np.isfinite(states_pos[:, 0])
    gap_share = _gap_share(take, tk, gaps)
    win = rate_filter.window_frames(ms.rate_window_s, rate, ms.rate_polyorder)
    if win > int((tk >= 0).sum()):
        raise MocapError(
            take.path,
            take.name,
            "rates.window_s",
            f"the rates' window ({win} frames, {win / rate:.3f} s at {rate:g} Hz) is longer than the "
            f"{int((tk >= 0).sum())} frames kept after contact: no rate could be made; shorten "
            "rates.window_s in the marker set",
        )
    rates = rate_filter.savgol_rates(states_pos, dt, win, ms.rate_polyorder)
    states = np.column_stack([states_pos, rates])

    cond = _conditions(
        c,
        {
            "slope_deg": round(slope, 2),
            "speed": round(float(-(vel_c @ up)), 3),
            "horizontal_speed": round(float(vel_c @ frame[0]), 3),
            "pitch_deg": round(math.degrees(pitch_c), 2),
            "pitch_rate_dps": round(math.degrees(prate_c), 1),
        },
    )
    oop = _out_of_plane(ms, rm, pitch, q, keep, rel)

    fl_res = flight_residual(
        t, np.column_stack([q[:, 0], q[:, 2], pitch]), tc, np.array([0.0, -GRAVITY, 0.0])
    )
    if ms.rigid_body is not None:
        pos_sd = float(np.mean(fl_res[:2]))
        ang_sd = float(fl_res[2])
    runs = _runs(gaps)
    quality = {
        "rate_hz": rate,
        "frames": int(keep.sum()),
        "before_contact_s": round(float(-tk[0]), 4),
        "after_contact_s": round(float(tk[-1]), 4),
        "gaps": [{"start_s": round(float(tk[s]), 4), "frames": ln} for s, ln in runs],
        "gap_share_after_contact": round(gap_share, 4),
        "contact_time_in_take_s": round(tc, 5),
        "contact_sd_s": round(ct.sd, 5),
        "contact_from": contact_from,
        "planar": not oop.over,
        "lateral_m": round(oop.lateral, 5),
        "yaw_deg": round(oop.yaw_deg, 2),
        "roll_deg": round(oop.roll_deg, 2),
        "roof_rms_m": round(roof_rms, 5),
        "free_fall_m_s2": round(g_meas, 3),
    }
    meta = {
        "rates": rate_filter.describe(win, ms.rate_polyorder, dt),
        "noise": _noise_meta(ms, (pos_sd, ang_sd), fl_res, marker_sd, len(c.body_idx)),
        "quality": quality,
        "provenance": _provenance(take, ms, up_note, used, turned),
    }
    outcome = c.entry.get("outcome")
    drop = Drop(
        drop_name(path),
        np.round(tk, 6),
        states,
        cond,
        Outcome[outcome.upper()] if outcome else None,
        f"{path.name} ({take.fmt}), take '{take.name}', imported by slopelander",
        meta,
    )
    line1 = _impact_line(drop.name, cond, ct, contact_from, bool(c.feet_idx))
    line2 = _data_line(rate, tk, _gap_text(runs, gaps, dt, tk), (pos_sd, ang_sd), oop)
    return Imported(drop, not oop.over, (line1, line2))


def import_takes(
    paths: list[Path], markers: Path, out: Path, *, keep_nonplanar: bool = False
) -> list[Imported]:
    """Import every take into the dataset folder ``out`` (which must not hold drops yet).
    Takes not planar enough go to ``out/not-planar/`` unless ``keep_nonplanar``."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise MocapError(out, None, "--out", "exists and is not an empty folder")
    if not out.parent.is_dir():
        raise MocapError(out, None, "--out", f"folder {out.parent} does not exist")
    ms = load_markerset(markers)
    files = take_files(paths, ms.takes_table)
    checked = [check_take(p, ms) for p in files]  # every take checked before any is solved
    done = [solve_take(c, ms) for c in checked]
    tmp = out.parent / f".{out.name}.importing-{os.getpid()}"
    try:
        tmp.mkdir()
        for d in done:
            write_drop(d.drop, tmp if (d.planar or keep_nonplanar) else tmp / "not-planar")
        if out.exists():
            out.rmdir()
        tmp.rename(out)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return done
