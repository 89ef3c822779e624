"""A landing from a flight log against the model run at its conditions, on what the log can see:
pitch and pitch rate, the body's acceleration, the impact (its time and size), the time to rest
and the travel downhill. Time runs from first contact (:mod:`.landings`); the model is observed
through the autopilot's filters (:mod:`.observe`)."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slopelander.ident.flightlog.conditions import Conditions, Given, landing_conditions
from slopelander.ident.flightlog.landings import LandingEvents, contact_time, find_landings
from slopelander.ident.flightlog.observe import ModelView, first_peak, impact_peak, observe, rest_time
from slopelander.ident.flightlog.reader import FlightLog, FlightLogError, read_log
from slopelander.model import Model
from slopelander.model.conditions import reverse_text

BEFORE_S = 0.3
"""s of the log kept (and drawn) before first contact."""
MIN_AFTER_S = 0.3
"""s of log a landing needs after first contact to be compared."""
END_S = 0.25
"""s at the end of the compared span over which the final pitch is averaged."""


@dataclass(frozen=True)
class Measured:
    """The log's view of one landing, time in s from first contact."""

    t_imu: np.ndarray
    gyro_dps: np.ndarray
    """(n, 3) body rates, deg/s"""
    accel: np.ndarray
    """(n, 3) specific force forward, right, down, m/s^2"""
    t_att: np.ndarray
    pitch_deg: np.ndarray
    t_ekf: np.ndarray
    speed: np.ndarray
    along: np.ndarray
    """m along the heading from where the body was at contact"""


@dataclass
class LandingComparison:
    """One landing of a log and the model at its conditions."""

    log: FlightLog
    events: LandingEvents
    landings: int
    contact: float
    rise: float
    cond: Conditions
    measured: Measured
    model: ModelView
    span: float
    """s after contact compared"""
    figures: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    errors: dict[str, float] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return f"{self.log.path.stem}-landing{self.events.number}"

    # -- figures ---------------------------------------------------------------------------
    def evaluate(self) -> None:
        me, mo, T = self.measured, self.model, self.span
        lm = (me.t_imu >= 0) & (me.t_imu <= T)
        mm = mo.t <= T
        # the model's accelerometer where the log's was sampled: both peaks are read on one grid
        t_imu = me.t_imu[me.t_imu >= 0]
        mag_log = np.linalg.norm(me.accel[me.t_imu >= 0], axis=1)
        mag_model = np.hypot(np.interp(t_imu, mo.t, mo.accel[:, 0]), np.interp(t_imu, mo.t, mo.accel[:, 1]))
        for what, find in (("first contact's peak", first_peak), ("largest peak", impact_peak)):
            a, b = find(t_imu, mag_log), find(t_imu, mag_model)
            self.figures[f"{what}, m/s^2"] = (a[1] if a else None, b[1] if b else None)
            self.figures[f"{what} after contact, s"] = (a[0] if a else None, b[0] if b else None)
        am = (me.t_att >= 0) & (me.t_att <= T)
        self.figures["lowest pitch, deg"] = (
            float(me.pitch_deg[am].min()) if am.any() else None,
            float(mo.pitch_deg[mm].min()),
        )
        end_log = am & (me.t_att >= T - END_S)
        end_model = mm & (mo.t >= T - END_S)
        self.figures[f"pitch at {T:.2f} s, deg"] = (
            float(me.pitch_deg[end_log].mean()) if end_log.any() else None,
            float(mo.pitch_deg[end_model].mean()),
        )
        speed_at_imu = np.interp(me.t_imu, me.t_ekf, me.speed)
        rest_log = rest_time(me.t_imu[lm], np.linalg.norm(me.gyro_dps[lm], axis=1), speed_at_imu[lm])
        rest_model = rest_time(mo.t[mm], mo.pitch_rate_dps[mm], mo.speed[mm])
        self.figures["time to rest, s"] = (rest_log, rest_model)
        em = (me.t_ekf >= 0) & (me.t_ekf <= T)
        self.figures[f"travel downhill by {T:.2f} s, m"] = (
            float(me.along[em][-1]) if em.any() else None,
            float(np.interp(T, mo.t, mo.x) - mo.x[0]),
        )
        self.errors["pitch, deg"] = _rms(np.interp(me.t_att[am], mo.t, mo.pitch_deg) - me.pitch_deg[am])
        rate = np.interp(me.t_imu[lm], mo.t, mo.pitch_rate_dps)
        self.errors["pitch rate, deg/s"] = _rms(rate - me.gyro_dps[lm, 1])
        for i, axis in enumerate(("forward", "down")):
            sim = np.interp(me.t_imu[lm], mo.t, mo.accel[:, i])
            self.errors[f"acceleration {axis}, m/s^2"] = _rms(sim - me.accel[lm, 2 * i])

    # -- output ----------------------------------------------------------------------------
    def heading_lines(self) -> list[str]:
        ev, c = self.events, self.cond.conditions
        thrust = "no reverse thrust"
        if c.reverse_percent > 0:
            held = "held" if math.isinf(c.reverse_duration) else f"for {c.reverse_duration:.2f} s"
            thrust = f"{reverse_text(c.reverse_percent)} after {c.reverse_delay:.3f} s {held}"
            thrust += f", ramp {c.reverse_ramp:.2f} s"
        lines = [
            f"{self.log.path.name} ({self.log.kind}): landing {ev.number} of {self.landings}, first contact "
            f"at {self.contact:.3f} s (motors cut at {ev.cut:.3f} s"
            + (f", reverse thrust at {ev.reverse:.3f} s" if ev.reverse is not None else "")
            + f"); compared over {self.span:.2f} s",
            f"  conditions: slope {c.slope_deg:.1f} deg, impact {c.speed:.2f} m/s down, "
            f"{c.horizontal_speed:+.2f} m/s along the heading, pitch {c.pitch_deg:+.1f} deg, "
            f"{c.pitch_rate_dps:+.0f} deg/s; legs {c.tau_up:.2f}/{c.tau_down:.2f} N*m, angles "
            f"{c.angle_up_deg:.1f}/{c.angle_down_deg:.1f} deg; {thrust}",
        ]
        lines += [f"    {k}: {v}" for k, v in self.cond.sources.items()]
        return lines

    def table(self) -> str:
        rows = ["| quantity | log | model | model - log |", "|---|---:|---:|---:|"]
        for name, (a, b) in self.figures.items():
            d = "-" if a is None or b is None else _num(b - a, signed=True)
            rows.append(f"| {name} | {_num(a)} | {_num(b)} | {d} |")
        for name, v in self.errors.items():
            rows.append(f"| RMS difference: {name} | - | - | {_num(v)} |")
        return "\n".join(rows)

    def lines(self) -> list[str]:
        out = self.heading_lines() + self.table().splitlines()
        out.append(f"  model outcome: {self.model.outcome.label}")
        out += [f"  note: {n}" for n in self.cond.notes + self.log_notes()]
        return out

    def log_notes(self) -> list[str]:
        notes = []
        if self.log.truncated:
            notes.append(self.log.truncated)
        if "not in the log" in str(self.log.filters.get("source")):
            notes.append(f"IMU filters: {self.log.filters['source']}")
        return notes

    def to_dict(self) -> dict:
        ev, c = self.events, self.cond
        return {
            "schema": "slopelander.log-landing/1",
            "log": {
                "file": str(self.log.path),
                "kind": self.log.kind,
                "landing": ev.number,
                "landings": self.landings,
                "truncated": self.log.truncated,
                "imu": _described(self.log.imu),
                "attitude": _described(self.log.attitude),
                "velocity": _described(self.log.ekf),
                "filters": self.log.filters,
            },
            "times_s": {
                "first_contact": self.contact,
                "cut": ev.cut,
                "cut_from": ev.cut_source,
                "reverse": ev.reverse,
                "reverse_left": ev.reverse_left,
                "hold": ev.hold,
                "end": ev.end,
                "end_is": ev.end_why,
                "contact_rise_mps2": self.rise,
                "compared_s": self.span,
            },
            "conditions": c.conditions.as_file_dict(),
            "sources": c.sources,
            "slope_estimate": None
            if c.slope is None
            else {k: v for k, v in c.slope.record().items() if k != "points"},
            "heading_deg": math.degrees(c.heading_rad),
            "figures": {k: {"log": a, "model": b} for k, (a, b) in self.figures.items()},
            "rms_difference": self.errors,
            "model_outcome": self.model.outcome.name.lower(),
            "notes": c.notes + self.log_notes(),
        }

    def plot(self, path: Path) -> Path:
        from slopelander.ident.flightlog.plot import plot_comparison

        return plot_comparison(self, path)


def _described(s) -> dict:
    return {"source": s.source, "rate_hz": round(s.rate_hz, 1), "samples": len(s)}


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if len(x) else float("nan")


def _num(v: float | None, signed: bool = False) -> str:
    if v is None:
        return "none"
    if not math.isfinite(v):
        return "-"
    text = f"{v:+.3g}" if signed else f"{v:.3g}"
    return "0" if text in ("-0", "+0") else text


def _measured(log: FlightLog, contact: float, end: float, psi: float) -> Measured:
    imu = log.imu.between(contact - BEFORE_S, end)
    att = log.attitude.between(contact - BEFORE_S, end)
    e = log.ekf.between(contact - BEFORE_S, end)
    c, s = math.cos(psi), math.sin(psi)
    along = e.v[:, 3] * c + e.v[:, 4] * s
    along0 = float(np.interp(contact, e.t, along)) if len(e) else 0.0
    return Measured(
        t_imu=imu.t - contact,
        gyro_dps=np.degrees(imu.v[:, :3]),
        accel=imu.v[:, 3:6],
        t_att=att.t - contact,
        pitch_deg=np.degrees(att.v[:, 1]),
        t_ekf=e.t - contact,
        speed=np.linalg.norm(e.v[:, :3], axis=1),
        along=along - along0,
    )


def compare_landing(
    model: Model, log: FlightLog, ev: LandingEvents, landings: int, given: Given
) -> LandingComparison:
    """One landing of ``log`` against ``model``: its contact, conditions and figures."""
    contact, rise = contact_time(log, ev)
    end, why = ev.end, ev.end_why
    for s in (log.imu, log.attitude):
        if s.t[-1] < end:
            end, why = float(s.t[-1]), f"the last {s.source} sample"
    after = end - contact
    if after < MIN_AFTER_S:
        more = f"; {log.truncated}" if log.truncated else ""
        raise FlightLogError(
            log.path,
            f"landing {ev.number}: the log holds only {after:.2f} s after first contact ({why} at "
            f"{end:.3f} s{more}); {MIN_AFTER_S:g} s are needed",
        )
    cond = landing_conditions(log, ev, contact, given)
    span = min(after, model.criteria.horizon + cond.conditions.thrust_off_time)
    a0 = (float(log.imu.at(contact, 3)), float(log.imu.at(contact, 5)))
    view = observe(model, cond.conditions, span, log.filters, a0)
    span = min(span, float(view.t[-1]))
    out = LandingComparison(
        log, ev, landings, contact, rise, cond, _measured(log, contact, ev.end, cond.heading_rad), view, span
    )
    out.evaluate()
    return out


def compare_log(
    model: Model, path: str | Path, given: Given | None = None, landing: int | None = None
) -> list[LandingComparison]:
    """Every landing of the log at ``path`` (or only number ``landing``) against ``model``.
    Raises :class:`FlightLogError` before any output when the log cannot be used."""
    log = read_log(path)
    found = find_landings(log)
    if landing is not None:
        if not 1 <= landing <= len(found):
            raise FlightLogError(log.path, f"--landing {landing}: the log holds {len(found)} landing(s)")
        chosen = [found[landing - 1]]
    else:
        chosen = found
    return [compare_landing(model, log, ev, len(found), given or Given()) for ev in chosen]


def write_results(
    results: list[LandingComparison], folder: Path, json_file: Path | None = None
) -> list[Path]:
    """Each landing's JSON and plot into ``folder`` (created), and with ``json_file`` every
    landing's JSON in one list there; written under temporary names and renamed once all are
    drawn: a failure leaves none of them half-written."""
    folder.mkdir(exist_ok=True)
    staged: list[tuple[Path, Path]] = []
    try:
        if json_file is not None:
            tmp = json_file.with_name(f".{json_file.name}.part")
            tmp.write_text(json.dumps([_finite(r.to_dict()) for r in results], indent=1) + "\n")
            staged.append((tmp, json_file))
        for r in results:
            js = folder / f".{r.name}.json.part"
            js.write_text(json.dumps(_finite(r.to_dict()), indent=1) + "\n")
            staged.append((js, folder / f"{r.name}.json"))
            png = folder / f".{r.name}.part.png"
            r.plot(png)
            staged.append((png, folder / f"{r.name}.png"))
    except BaseException:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        raise
    for tmp, final in staged:
        os.replace(tmp, final)
    return [final for _, final in staged]


def _finite(v):
    """``v`` for JSON: numpy numbers as Python's, infinities and NaN as null."""
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    if isinstance(v, (np.floating, np.integer)):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
