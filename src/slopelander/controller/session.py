"""One landing session: the flight path that ``slopelander land``, the demo and the test rig fly.

connect → ask for the streams (one table, :data:`STREAMS`) → measure the slope (a survey pass when
needed) → plan the legs (table, pilot switch, calibration) → open the leg board on the vehicle's
clock → land (:class:`slopelander.controller.runner.Lander`) → settle the link's last commands.

A fix to any of these steps is made here once; the callers add only what is theirs: ``land`` its
arguments, checks and Ctrl-C handling, the demo its take-off and flight over the roof, the rig its
faults and measurements. With an output folder the session writes the evidence a pilot reads after
a flight: the MAVLink telemetry log, the state transitions, the slope estimate and the outcome.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import IO

from slopelander.controller.config import Config
from slopelander.controller.landing import (
    LegPreset,
    contact_range,
    cut_dynamics,
    landing_cut_height,
    leg_geometry,
    plan_landing,
)
from slopelander.controller.link import LANDING_MESSAGES, AutopilotInfo, Link, mavlink
from slopelander.controller.rc_presets import preset_for
from slopelander.controller.runner import Lander
from slopelander.controller.slope_estimate import SlopeEstimate, SurfaceTrack
from slopelander.controller.table import LookupTable
from slopelander.controller.telemetry import Telemetry
from slopelander.errors import SlopelanderError

#: The streams every landing asks the autopilot for (MAV_CMD_SET_MESSAGE_INTERVAL), each with the
#: settings key of its rate. The impact detector reads RAW_IMU, the cut and the slope read
#: DISTANCE_SENSOR, rest and slide are told from LOCAL_POSITION_NED, a range is a height only with
#: the ATTITUDE it was taken at, the pilot's preset switch is on RC_CHANNELS, the motors' outputs
#: (SERVO_OUTPUT_RAW) are the log's evidence of the cut and the reverse thrust, a take-off's
#: target is a height above home (GLOBAL_POSITION_INT's relative altitude), and HEARTBEAT
#: faster than ArduPilot's 1 Hz keeps a slowed simulation from reading as a lost link.
STREAMS: tuple[tuple[str, str], ...] = (
    ("HEARTBEAT", "link.heartbeat_hz"),
    ("RAW_IMU", "link.imu_hz"),
    ("DISTANCE_SENSOR", "link.range_hz"),
    ("LOCAL_POSITION_NED", "link.position_hz"),
    ("ATTITUDE", "link.attitude_hz"),
    ("RC_CHANNELS", "link.rc_hz"),
    ("SERVO_OUTPUT_RAW", "link.servo_hz"),
    ("GLOBAL_POSITION_INT", "link.home_alt_hz"),
)
#: what a session decodes: the landing's messages and the motors' outputs for the log
SESSION_MESSAGES = LANDING_MESSAGES | {"SERVO_OUTPUT_RAW"}
#: local seconds to wait for the autopilot to answer the stream requests
STREAM_ANSWER_S = 10.0
#: local seconds the leg board has to answer the handshake (resent every 0.25 s): a board answers
#: in milliseconds, a simulated one on a loaded machine took over 2 s (two busy processes beside
#: the suite, 2026-12-07); a missing board is reported this much later
LEGS_HANDSHAKE_S = 5.0


class SessionError(SlopelanderError):
    """A step of the session could not be done (a stream refused, no clock, no board)."""


@dataclass
class SlopeChoice:
    """The slope a landing is planned for and what it was checked against."""

    slope_deg: float | None  # None: refused (``refusal`` says why)
    estimate: SlopeEstimate | None
    bound_deg: float | None
    survey_s: float = 0.0
    refusal: str | None = None


class Session:
    """A link to one autopilot and, once opened, its leg board, flown through the landing steps.

    ``out`` (a folder, created by the caller) receives ``flight.tlog`` at once and, as the steps
    run, ``transitions.jsonl`` and ``slope_estimate.json``. ``record`` (a file-like) also receives
    every transition, e.g. to print it as it happens. ``lockstep``: the autopilot is a simulator
    that waits for the companion's echo (:mod:`slopelander.controller.link.lockstep`)."""

    def __init__(
        self,
        url: str,
        cfg: Config,
        *,
        table: LookupTable | None = None,
        calibration=None,
        out: Path | None = None,
        decode: frozenset[str] | None = SESSION_MESSAGES,
        telemetry: bool = True,
        lockstep: bool = False,
        echo: Callable[[str], None] = print,
    ) -> None:
        self.cfg = cfg
        self.table = table
        self.calibration = calibration
        self.out = out
        self.echo = echo
        self.link = Link(url, link_loss_s=cfg["link.link_loss_s"], decode=decode, lockstep=lockstep)
        self.link.heartbeats_missed = cfg["link.heartbeats_missed"]
        if out is not None:
            self.link.conn.setup_logfile(str(out / "flight.tlog"), mode="wb")
        self.track = SurfaceTrack(cfg["slope.pair_window_s"])
        self.link.add_listener(self.track.feed)
        self.telemetry = Telemetry() if telemetry else None
        if self.telemetry is not None:
            self.link.add_listener(self.telemetry.listen)
        self.info: AutopilotInfo | None = None
        self.legs = None
        self.lander: Lander | None = None
        self._transitions: IO[str] | None = None

    # ------------------------------------------------------------------ steps
    def connect(
        self, timeout_s: float | None = None, streams: tuple[str, ...] | None = None
    ) -> AutopilotInfo:
        """Wait for the autopilot's heartbeat and ask for the streams (all of :data:`STREAMS`, or
        the ones named); a refused or unanswered request is a :class:`SessionError`."""
        self.info = self.link.wait_autopilot(timeout_s=timeout_s or self.cfg["link.heartbeat_wait_s"])
        self.request_streams(streams)
        return self.info

    def request_streams(
        self, names: tuple[str, ...] | None = None, tick: Callable[[], None] | None = None
    ) -> None:
        """Ask for the streams of :data:`STREAMS` (those in ``names``) at their configured rates and
        wait for every answer."""
        handles = []
        for name, key in STREAMS:
            if names is None or name in names:
                msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
                handles.append((name, self.link.request_stream(msg_id, self.cfg[key])))
        end = time.monotonic() + STREAM_ANSWER_S
        while time.monotonic() < end and not all(h.done for _, h in handles):
            (tick or self.link.poll)()
            time.sleep(0.002)
        for name, h in handles:
            if not h.ok:
                raise SessionError(f"the autopilot did not accept the {name} stream: {h.describe()}")

    def wait_clock(self, timeout_s: float = 30.0) -> None:
        """Poll until the vehicle's clock is known (its first timestamped message): the board's
        silence and every timeout of a landing are measured on it."""
        end = time.monotonic() + timeout_s
        while not self.link.clock.known and time.monotonic() < end:
            self.link.poll()
            time.sleep(0.002)
        if not self.link.clock.known:
            raise SessionError(f"the vehicle sent no timestamped message within {timeout_s:g} s")

    def open_legs(self, port: str, **kw):
        """Open the leg board on ``port`` (``kw`` to :meth:`LegBoard.open`: baud, timeout) with the
        session's calibration; its timeouts run on the vehicle's clock, as the landing's do: a
        simulation slowed by a loaded machine is not a silent board, and a real vehicle's clock
        runs with the local one."""
        from slopelander.legs.driver import LegBoard

        self.wait_clock()
        if self.legs is not None:
            self.legs.close()
            self.legs = None
        kw.setdefault("timeout", LEGS_HANDSHAKE_S)
        self.legs = LegBoard.open(port, calibration=self.calibration, **kw)
        self.legs.set_clock(self.link.clock.now)
        if self.link.lockstep is not None:  # the simulator waits for the board's bytes too
            self.link.lockstep.limit = self._legs_accounted
            self.link.lockstep.catch_up = self._legs_catch_up
        if self.telemetry is not None:
            self.telemetry.legs = self.legs
        return self.legs

    def _legs_accounted(self) -> float | None:
        """The vehicle time up to which the leg board is accounted for (None: no board)."""
        return None if self.legs is None else self.legs.accounted_until()

    def _legs_catch_up(self) -> None:
        """Read what the leg board has in flight, waiting for it (the simulator is held)."""
        if self.legs is not None:
            self.legs.catch_up()

    def measure_slope(
        self, pilot: float | str, *, tick: Callable[[], None] | None = None, wall_s: float = 300.0
    ) -> SlopeChoice:
        """The slope to land on. ``pilot`` is 'auto' (land on the measured slope, refused when it
        cannot be trusted) or the pilot's figure (deg), checked in CHECKS against the measured one
        unless ``slope.check_pilot`` is off (then nothing is measured)."""
        from slopelander.controller.slope_estimate import check_bound, slope_to_land
        from slopelander.controller.survey import measure_slope

        auto = pilot == "auto"
        if not auto and not self.cfg["slope.check_pilot"]:
            return SlopeChoice(float(pilot), None, None)
        est, took = measure_slope(self.link, self.cfg, self.track, tick=tick, note=self.echo, wall_s=wall_s)
        slopes = self.table.slopes if self.table is not None else []
        cell = max(b - a for a, b in pairwise(slopes)) if len(slopes) > 1 else 0.0
        bound = check_bound(
            float(cell),
            est.sigma_deg or 0.0,
            self.cfg["slope.check_sigmas"],
            self.cfg["slope.check_bound_deg"],
        )
        self.echo(f"slope measured: {est.describe()}" + (f" (survey pass {took:.1f} s)" if took else ""))
        choice = SlopeChoice(None if auto else float(pilot), est, bound, took)
        if auto:
            slope, why = slope_to_land(est, bound)
            if slope is not None and self.table is not None:
                lo, hi = self.table.slope_range
                if not lo <= slope <= hi:
                    slope, why = (
                        None,
                        f"measured slope {slope:.1f} deg is outside the lookup table's {lo:g}..{hi:g} deg",
                    )
            choice.slope_deg, choice.refusal = slope, why
            if slope is None:
                self.echo(f"refused: {why}")
                self.link.send_statustext(f"SL refused: {why}"[:50])
        if self.out is not None:
            entry = {"slope_estimate": est.record(), "bound_deg": bound, "survey_s": took}
            if choice.refusal:
                entry["refused"] = choice.refusal
            (self.out / "slope_estimate.json").write_text(json.dumps(entry, indent=1))
        return choice

    def plan(
        self, slope_deg: float, *, pilot_switch: bool = True, cfg: Config | None = None
    ) -> tuple[LegPreset, float]:
        """The legs' preset for ``slope_deg`` and the impact speed it was chosen for: the pilot's
        switch preset when one is selected (``pilot_switch``), else the table's, checked against the
        calibration. ``cfg``: this landing's settings, when not the session's."""
        cfg = cfg or self.cfg
        rc = preset_for(cfg, self.link.last.get("RC_CHANNELS")) if pilot_switch else None
        return plan_landing(
            cfg["descent.rate_mps"],
            cfg["reflex.cut_height_m"],
            slope_deg,
            leg_geometry(),
            self.table,
            rc,
            self.calibration,
            cut_dynamics(cfg["reflex.cut_latency_s"]),
        )

    def make_lander(
        self,
        preset: LegPreset | tuple[float, float],
        *,
        slope_deg: float | None,
        record: IO[str] | None = None,
        next_preset: tuple[float, float] | None = None,
        slope: SlopeChoice | None = None,
        uphill_angle_deg: float | None = None,
        cfg: Config | None = None,
    ) -> Lander:
        """The landing controller for one landing with ``preset`` (a :class:`LegPreset`, or the
        torques alone with ``uphill_angle_deg``). Its transitions go to ``record`` and, with an
        output folder, to ``transitions.jsonl``."""
        if isinstance(preset, LegPreset):
            torques, angle = (preset.tau_up, preset.tau_down), preset.angle_up_deg
        else:
            torques, angle = tuple(preset), uphill_angle_deg
        sink = record
        if self.out is not None:
            if self._transitions is None:
                self._transitions = (self.out / "transitions.jsonl").open("a")
            sink = _Tee(self._transitions, record)
        self.lander = Lander(
            self.link,
            self.landing_config(cfg or self.cfg, slope_deg, angle),
            torques,
            legs=self.legs,
            record=sink,
            next_preset=next_preset,
            uphill_angle_deg=angle,
            slope_deg=slope_deg,
            slope_estimate=None if slope is None else slope.estimate,
            slope_bound_deg=None if slope is None else slope.bound_deg,
        )
        return self.lander

    def landing_config(
        self, cfg: Config, slope_deg: float | None, uphill_angle_deg: float | None, *, say: bool = True
    ) -> Config:
        """``cfg`` with the landing's cut height (:func:`landing_cut_height`): raised, and said
        (``say``), where the uphill foot would touch the roof before the motors stop. A landing not
        told its slope keeps the configured cut."""
        set_m = cfg["reflex.cut_height_m"]
        if slope_deg is None:
            return cfg
        geom = leg_geometry()
        cut = landing_cut_height(set_m, cfg["descent.rate_mps"], slope_deg, geom, uphill_angle_deg)
        if cut <= set_m:
            return cfg
        touch = contact_range(slope_deg, geom, uphill_angle_deg)
        if say:
            self.echo(
                f"cut height raised from {set_m:.2f} to {cut:.2f} m: on the {slope_deg:.1f} deg roof the "
                f"uphill foot touches at a range of {touch:.2f} m"
            )
        why = f"cut raised for a {slope_deg:.1f} deg roof"
        return cfg.with_values({"reflex": {"cut_height_m": cut}}, why)

    def hand_to_loiter(self, wait_s: float = 3.0) -> bool:
        """Stop where the vehicle is: a zero-velocity setpoint first (a survey pass's target
        moves on otherwise, until GUID_TIMEOUT), then LOITER; True once the autopilot reports
        LOITER (or is disarmed) within ``wait_s`` local seconds."""
        from slopelander.controller.actions import MODES, MavActions

        act = MavActions(self.link, self.cfg)
        act.hold(0.0)
        act.set_mode("LOITER")
        end = time.monotonic() + wait_s
        while time.monotonic() < end:
            self.link.poll()
            hb = self.link.last.get("HEARTBEAT")
            armed = hb is not None and hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
            if hb is not None and (not armed or hb.custom_mode == MODES["LOITER"]):
                return True
            time.sleep(0.01)
        return False

    def settle(self) -> int:
        """Let the last commands be answered before the link closes; how many were not."""
        return self.link.settle()

    def close(self) -> None:
        """Close the transitions file, the leg board and the link (each once)."""
        if self._transitions is not None:
            self._transitions.close()
            self._transitions = None
        if self.legs is not None:
            self.legs.close()
            self.legs = None
        self.link.close()

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Tee:
    """A transitions sink writing to the session's file and to the caller's, if any."""

    def __init__(self, first: IO[str], second: IO[str] | None) -> None:
        self.first, self.second = first, second

    def write(self, text: str) -> int:
        self.first.write(text)
        if self.second is not None:
            self.second.write(text)
        return len(text)

    def flush(self) -> None:
        self.first.flush()
        if self.second is not None:
            self.second.flush()


def read_transitions(path: Path) -> list[dict]:
    """The state transitions in a landing's ``transitions.jsonl`` (``t``, ``from``, ``to``,
    ``reason``), in order. The file also holds, before each landing's transitions, the slope
    measured for it (an entry with ``slope_estimate``: docs/slope-estimate.md); those are left out.
    A line that is not JSON (a landing cut off mid-write) is left out too."""
    out = []
    for line in Path(path).read_text().splitlines():
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(entry, dict) and "to" in entry:
            out.append(entry)
    return out
