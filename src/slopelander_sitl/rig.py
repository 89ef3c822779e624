"""A flight rig for tests and benchmarks: the simulated vehicle and leg board as real processes,
the companion's landing controller (:class:`slopelander.controller.runner.Lander`) flying them
through the real MAVLink endpoint and the real pseudo-terminal, in lock-step.

    with Rig(slope_deg=35) as rig:
        rig.take_off()
        rig.go_over_roof(height_m=2.0)
        flight = rig.land((1.7, 2.3))
        print(flight.end, flight.contact, flight.classify())

One vehicle can fly many landings: after a landing, :meth:`Rig.take_off_again` runs the
controller's TAKEOFF → RESET → READY sequence, and :meth:`Rig.go_over_roof` brings it back to a
start height for the next one. The vehicle's measurement events (``src/slopelander_sitl/vehicle/events.py``:
contact, outputs stopped, outputs reversed) are collected in :attr:`Rig.track`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from slopelander.controller.config import Config, load_config, merge
from slopelander.controller.link import Link
from slopelander.controller.runner import Lander
from slopelander.controller.script_rules import MOTORS_HELD
from slopelander.controller.session import SESSION_MESSAGES, Session, SessionError
from slopelander.controller.table import DEFAULT_TABLE, LookupTable
from slopelander.legs.calibration import load_calibration
from slopelander.legs.driver import LegBoard
from slopelander.legs.errors import LegTimeout
from slopelander_sitl.guided import THROTTLE_DOWN_US, arm_in_guided, throttle_override
from slopelander_sitl.linkfault import Relay
from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle

ROOF_X_M = 3.0
ROOF_Z_M = 0.5
OVER_ROOF_X_M = 5.5
#: m between the ridge and the straight line the vehicle's origin flies over it (its feet hang
#: about 0.2 m below the origin; ArduCopter's descent is slower than its forward flight, so its
#: path bends above the straight line)
RIDGE_CLEARANCE_M = 0.3
#: the rig's stream rates (the session's table, controller/session.py): the flight tests read the
#: track at 50 Hz. A lock-stepped vehicle may run slower than real time on a loaded machine, while
#: the companion counts link silence in local time: heartbeats at 5 Hz of vehicle time keep a slow
#: simulation from reading as a lost link (ArduPilot honours SET_MESSAGE_INTERVAL for HEARTBEAT).
RIG_RATES = {"heartbeat_hz": 5, "position_hz": 50, "attitude_hz": 50, "servo_hz": 50, "rc_hz": 10}
#: the streams a rig without ``telemetry`` asks for
BARE_STREAMS = ("HEARTBEAT", "RAW_IMU", "DISTANCE_SENSOR", "LOCAL_POSITION_NED")


#: the autopilots a rig can fly: the project's simulated vehicle, or real ArduCopter SITL
#: (``SLOPELANDER_ARDUCOPTER``) behind the same physics
AUTOPILOTS = ("sim", "ardupilot")


def add_autopilot_args(ap) -> None:
    """The options of a benchmark that flies either autopilot: ``--autopilot``, ``--arducopter``
    and ``--speedup`` (ArduCopter's)."""
    ap.add_argument(
        "--autopilot", choices=AUTOPILOTS, default="sim", help="the simulated vehicle or ArduCopter"
    )
    ap.add_argument(
        "--arducopter", metavar="PATH", help="ArduCopter SITL binary (else $SLOPELANDER_ARDUCOPTER)"
    )
    ap.add_argument(
        "--speedup",
        type=float,
        default=4.0,
        help="ArduCopter's --speedup, the most it runs ahead of real time (the physics holds it "
        "while the companion is behind: src/slopelander_sitl/json_physics/companion_gate.py)",
    )


#: what the rig's :class:`Track` reads: the session's messages
TRACK_MESSAGES = SESSION_MESSAGES


#: wall seconds the rig's lock-stepped vehicle waits for the companion before running free (the
#: vehicle's default is 1 s): on a machine loaded by a parallel test suite the companion has
#: stalled past 1 s, and the vehicle then ran free at up to 8x real time through the landing's
#: timing (the thrust's end, the settle), making 55 deg landings end by the script's bound
LOCKSTEP_PATIENCE_S = 5.0
#: wall seconds the rig gives its simulated leg board to answer the handshake (a session gives a
#: board 5 s, a real one answers in milliseconds): the simulated board is a relay and a firmware
#: process, and beside a parallel suite and two busy processes it once took longer than 5 s
BOARD_HANDSHAKE_S = 15.0
#: the rig's default speed-up for real ArduCopter (see :class:`Rig`)
ARDUCOPTER_SPEEDUP = 8.0
#: s of vehicle time the rig flies a landing on once the controller holds it in SETTLED after a
#: slide (armed on the roof, motors held, the pilot told: the controller waits for the pilot and has
#: no end of its own). Such landings ran to the test's wall-clock ``timeout_s`` before: 20-45 s of
#: every process stepping at full speed for a hold whose checks need a few seconds of it.
HELD_S = 5.0


class RigError(RuntimeError):
    """The rig could not fly what was asked (the vehicle did not get there in time)."""


def config(**sections: dict[str, Any]) -> Config:
    """The shipped controller settings with ``sections`` overriding them, e.g.
    ``config(reflex={"cut_height_m": 0.5})``."""
    base = load_config()
    return Config(merge(base.doc, sections, "rig"), "rig")


@dataclass
class Track:
    """What the companion saw, in vehicle time (s)."""

    pos: list[tuple[float, float, float, float, float]] = field(default_factory=list)  # t, x, z up, vx, vz up
    pitch: list[tuple[float, float]] = field(default_factory=list)  # t, deg
    servo: list[tuple[float, tuple[int, ...]]] = field(default_factory=list)
    events: list[tuple[str, float, float]] = field(default_factory=list)  # name, t, value
    script: list[tuple[float, int]] = field(default_factory=list)  # SL_STATE changes
    ranges: list[tuple[float, float]] = field(default_factory=list)  # t, downward range (m)
    statustext: list[str] = field(default_factory=list)

    def trim(self, before: float) -> None:
        """Forget the samples older than vehicle time ``before`` (s): a long run (the soak) keeps
        only what it still reads, so the recorder does not grow with the vehicle's life. The
        status texts are kept: they are read by position."""
        self.pos = [p for p in self.pos if p[0] >= before]
        self.pitch = [p for p in self.pitch if p[0] >= before]
        self.servo = [p for p in self.servo if p[0] >= before]
        self.ranges = [p for p in self.ranges if p[0] >= before]
        self.script = [p for p in self.script if p[0] >= before]
        self.events = [e for e in self.events if e[1] >= before]

    def listen(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "LOCAL_POSITION_NED":
            self.pos.append((msg.time_boot_ms / 1000.0, msg.x, -msg.z, msg.vx, -msg.vz))
        elif kind == "ATTITUDE":
            self.pitch.append((msg.time_boot_ms / 1000.0, math.degrees(msg.pitch)))
        elif kind == "SERVO_OUTPUT_RAW":
            self.servo.append(
                (msg.time_usec / 1e6, tuple(getattr(msg, f"servo{i}_raw") for i in range(1, 5)))
            )
        elif kind == "STATUSTEXT":
            self.statustext.append(msg.text)
        elif kind == "DISTANCE_SENSOR":
            self.ranges.append((msg.time_boot_ms / 1000.0, msg.current_distance / 100.0))
        elif kind == "NAMED_VALUE_FLOAT":
            name = msg.name.rstrip("\x00")
            if name == "SL_STATE":
                if not self.script or self.script[-1][1] != int(msg.value):
                    self.script.append((msg.time_boot_ms / 1000.0, int(msg.value)))
            elif name.startswith(("EV_", "CT_")):
                self.events.append((name, msg.time_boot_ms / 1000.0, float(msg.value)))

    def event_times(self, name: str, after: float = -math.inf) -> list[float]:
        """Times (s, sub-ms) of the events called ``name`` later than ``after``."""
        return [v for n, t, v in self.events if n == name and v > after]

    def contact(self, after: float) -> dict[str, float] | None:
        """The first contact after vehicle time ``after``: its time and the body state then."""
        for name, ms, value in self.events:
            if name == "EV_CONTACT" and value > after:
                out = {"t": value}
                for n, tt, v in self.events:
                    if n.startswith("CT_") and tt == ms and n[3:].lower() not in out:
                        out[n[3:].lower()] = v
                return out
        return None


@dataclass
class Flight:
    """One landing as the companion flew it and the vehicle reported it."""

    end: str
    history: list[dict]
    preset: tuple[float, float]
    cfg: Config
    t_start: float
    contact: dict[str, float] | None
    track: Track
    lander: Lander
    leg_angles_deg: tuple[float, float] = (37.5, 37.5)

    def model_conditions(self, thrust: str = "flown"):
        """The model's :class:`LandingConditions` for what the vehicle reported at contact: its
        slope, vertical and horizontal speed, pitch and rate, the preset, the leg angles, and the
        reverse thrust with the delay the vehicle measured from contact to reversed outputs.

        ``thrust="flown"`` ends the reverse thrust as it was flown. The script's RVT state (12)
        began at the vehicle's EV_RVT and left for HOLD (13) at the end of the ramp
        (``reflex.reverse_ramp_ms``), so the thrust was held until that time less the ramp;
        leaving RVT for another state (a disarm, the emergency stop) stopped the outputs at
        once. A flight handed to the pilot ends before the script's HOLD is heard: then the ramp
        began when the companion ended the thrust (its SETTLED state, within a few ms of the
        script's ramp in the flights). Held past ``reflex.reverse_max_ms``, the script's own
        bound ended it: held to the bound, then its ramp until RVT was left (a ramp cut short
        reads as a steeper one). An RVT seen to end neither way is held.
        ``thrust="held"`` keeps it on to the model's horizon, as the maps and the table assume."""
        from slopelander.model.conditions import MAX_REVERSE_DURATION, LandingConditions

        if thrust not in ("flown", "held"):
            raise ValueError(f"thrust must be 'flown' or 'held', not {thrust!r}")
        c = self.contact
        if c is None:
            raise RigError("no contact reported: nothing to compare")
        pct = float(self.cfg["reflex.reverse_thrust_pct"])
        rvt = self.track.event_times("EV_RVT", c["t"] - 0.001)
        delay = min(5.0, rvt[0] - c["t"]) if (pct > 0 and rvt) else 0.0
        duration, ramp = math.inf, 0.0
        if pct > 0 and rvt and thrust == "flown":
            full_ramp = float(self.cfg["reflex.reverse_ramp_ms"]) / 1000.0
            # the script's states from contact on (RVT begins within ms of it; its SL_STATE
            # times are in ms), and the first state it went to after RVT
            after = [(t, code) for t, code in self.track.script if t >= c["t"] - 0.01]
            i = next((n for n, (_, code) in enumerate(after) if code == 12), None)
            left = (
                next(((t, code) for t, code in after[i + 1 :] if code != 12), None) if i is not None else None
            )
            settled = next((h["t"] for h in self.history if h["to"] == "SETTLED" and h["t"] >= rvt[0]), None)
            ramp_start = None
            if left is not None:
                ramp = full_ramp if left[1] == 13 else 0.0
                ramp_start = left[0] - ramp
            elif settled is not None:
                ramp, ramp_start = full_ramp, settled
            if ramp_start is not None:
                held = ramp_start - rvt[0]
                bound = float(self.cfg["reflex.reverse_max_ms"]) / 1000.0
                if held > bound + 0.05:  # the script's own bound ended it, and its ramp ran until left
                    ramp = min(full_ramp, max(0.0, ramp_start + ramp - rvt[0] - bound))
                    held = bound
                if held <= 0.0:  # ended within the reversal: what was left of the ramp ran
                    ramp, held = max(0.0, ramp + held), 1e-3
                duration = min(MAX_REVERSE_DURATION, held)
        return LandingConditions(
            slope_deg=c["slope"],
            speed=max(0.0, c["vz"]),
            horizontal_speed=c["vx"],
            pitch_deg=c["pitch"],
            pitch_rate_dps=c["rate"],
            tau_up=self.preset[0],
            tau_down=self.preset[1],
            angle_up_deg=self.leg_angles_deg[0],
            angle_down_deg=self.leg_angles_deg[1],
            reverse_percent=pct if rvt else 0.0,
            reverse_delay=max(0.0, delay),
            reverse_duration=duration,
            reverse_ramp=ramp,
        )

    @property
    def states(self) -> list[str]:
        return [h["to"] for h in self.history]

    @property
    def story(self) -> str:
        """The transitions on one line, every reason whole, for an assertion's message (a repr of
        the history is cut short by pytest, and with it the reason a landing went wrong)."""
        return " | ".join(f"{h['t']:.2f} {h['to']}: {h['reason']}" for h in self.history)

    def time_of(self, state: str) -> float | None:
        for h in self.history:
            if h["to"] == state:
                return h["t"]
        return None

    def classify(self, slope_deg: float, until: float | None = None) -> tuple[str, dict[str, float]]:
        """'landed', 'slid' or 'flipped' from the telemetry after contact (the model's criteria:
        more than 1 m along the slope or still moving = slid; pitch past -80 deg = flipped), and
        the figures behind it."""
        if self.contact is None:
            return "no contact", {}
        t0 = self.contact["t"]
        pos = [p for p in self.track.pos if p[0] >= t0 and (until is None or p[0] <= until)]
        pitch = [p for t, p in self.track.pitch if t >= t0 and (until is None or t <= until)]
        if not pos:
            return "no contact", {}
        c = math.cos(math.radians(slope_deg))
        x0 = pos[0][1]
        slide = max(abs(p[1] - x0) for p in pos) / c
        moving = math.hypot(pos[-1][3], pos[-1][4])
        figures = {
            "slide_m": slide,
            "min_pitch_deg": min(pitch),
            "final_pitch_deg": pitch[-1],
            "speed_end": moving,
        }
        if min(pitch) < -80.0 or max(pitch) > 80.0:
            return "flipped", figures
        if slide > 1.0 or moving > 0.05:
            return "slid", figures
        return "landed", figures


class Rig:
    """Leg board, vehicle and companion link, started together; ``close()`` stops them."""

    def __init__(
        self,
        slope_deg: float = 35.0,
        *,
        seed: int = 0,
        scenario: dict | None = None,
        speed: float = 8.0,
        imu_hz: float = 200.0,
        imu_message: int = mavlink.MAVLINK_MSG_ID_RAW_IMU,
        relay: bool = False,
        range_hz: float = 50.0,
        telemetry: bool = True,
        decode: frozenset[str] | None = TRACK_MESSAGES,
        script: bool | Path = True,
        autopilot: str = "sim",
        arducopter: str | None = None,
        extra_endpoints: list[str] | None = None,
        arducopter_speedup: float = ARDUCOPTER_SPEEDUP,
        out=None,
        arducopter_params: dict | None = None,
    ) -> None:
        """``arducopter_params``: parameters ArduCopter boots with over the project's parameter file
        (a test of a setting read at boot only). ``arducopter_speedup``: ArduCopter's
        ``--speedup``, the most it runs ahead of real time.
        It is lock-stepped with the physics, and the physics holds it while the companion is more
        than 0.25 s of vehicle time behind and keeps it to real time within 1.6 m of the ground while
        the script may be timing something (``slopelander_sitl.json_physics.companion_gate``): the
        companion's and the board's limits (1 s each, on the vehicle's time) hold on a loaded
        machine, and the on-board script, whose thread ArduPilot SITL runs in wall-clock steps,
        has real time for the cut and the impact. Above real time
        the climb, the transit and the wait for the legs cost less wall time and CPU (a 35 deg
        landing: 23.1 s and 40.7 CPU-s at 8x against 34.1 s and 47.2 CPU-s at 1x, 2026-11-27,
        benchmarks/arducopter_pace.py). Without the real time near the ground one landing's
        script saw the impact 170 ms after contact at 8x (7-10 ms at 1x); without the gate the
        reflex's validity lapsed in 3 of 24 landings at 4x and load 5-17 (2026-11-26)."""
        if autopilot not in AUTOPILOTS:
            raise ValueError(f"autopilot must be one of {', '.join(AUTOPILOTS)}, not {autopilot!r}")
        if not (math.isfinite(arducopter_speedup) and arducopter_speedup > 0):
            raise ValueError(f"arducopter_speedup must be a positive number, not {arducopter_speedup!r}")
        self.autopilot = autopilot
        self.slope_deg = slope_deg
        scn = {"slope_deg": float(slope_deg), "roof_x": ROOF_X_M, "roof_z": ROOF_Z_M, "seed": seed}
        scn.update(scenario or {})
        self.scenario = scn
        self.board = start_legboard(speed=speed, clock="external")
        self.vehicle = None
        self.session: Session | None = None
        self.link: Link | None = None
        self.legs: LegBoard | None = None
        self.calibration = None
        self.relay: Relay | None = None
        self.track = Track()
        self.last_flight: Flight | None = None  # for callers that fly a sequence of landings
        self._events_at = 0  # how far the physics' events file (real ArduCopter) has been read
        self.leg_silences: list[
            tuple[float, str]
        ] = []  # (vehicle time, what) the rig reopened the board after
        self._stick_held, self._stick_sent = False, -1e9  # pilot_stick_down_while_disarmed
        try:
            if autopilot == "ardupilot":
                from slopelander_sitl.ardupilot import start_arducopter

                self.vehicle = start_arducopter(
                    scenario=scn,
                    legs=self.board.control,
                    binary=arducopter,
                    script=script,
                    speedup=arducopter_speedup,
                    keep_log=None if out is None else Path(out) / "flight.bin",
                    params=arducopter_params,
                )
            else:
                self.vehicle = start_vehicle(
                    scenario=scn,
                    speed=speed,
                    lockstep=True,
                    legboard_control=self.board.control,
                    no_script=not script,
                    **({"script": script} if isinstance(script, Path) else {}),
                    extra_endpoints=extra_endpoints,
                    give_up_s=LOCKSTEP_PATIENCE_S,
                )
            url = self.vehicle.mavlink_url
            if relay:
                self.relay = Relay("tcp:127.0.0.1:0", url, lockstep=True).start()
                url = f"tcp:127.0.0.1:{self.relay.port}"
            self.calibration = load_calibration()
            self.session = Session(
                url,
                config(link={**RIG_RATES, "imu_hz": imu_hz, "range_hz": range_hz}),
                table=LookupTable.load(DEFAULT_TABLE),
                calibration=self.calibration,
                out=out,
                decode=decode,
                telemetry=out is not None,
                lockstep=True,
            )
            self.link = self.session.link
            self.link.add_listener(self.track.listen)
            try:
                self.info = self.session.connect(timeout_s=30.0, streams=None if telemetry else BARE_STREAMS)
                if imu_message != mavlink.MAVLINK_MSG_ID_RAW_IMU:
                    self.wait_command(self.link.request_stream(imu_message, imu_hz), f"stream {imu_message}")
            except SessionError as exc:
                raise RigError(str(exc)) from None
            self.open_legs()
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ plumbing
    def open_legs(self) -> LegBoard:
        """A fresh leg driver (the old one closed) whose silence and timeouts are measured on the
        vehicle's clock, as the landing controller measures them: a loaded machine that slows the
        lock-stepped simulation, and the board on its time, is not a silent board."""
        self.legs = None
        try:
            self.legs = self.session.open_legs(self.board.pty, timeout=BOARD_HANDSHAKE_S)
        except SessionError as exc:
            raise RigError(str(exc)) from None
        return self.legs

    def close(self) -> None:
        if self.session is not None:
            self.session.close()
            self.session = None
        self.legs = None
        self.link = None
        if self.relay is not None:
            self.relay.stop()
            self.relay = None
        if self.vehicle is not None:
            self.vehicle.stop()
            if getattr(self.vehicle, "summary", ""):  # ArduCopter's: how its physics waited for us
                print(self.vehicle.summary, flush=True)
            self.vehicle = None
        for t, why in self.leg_silences:  # a failed test's output says what the rig reopened
            print(f"rig: leg board reopened at {t:.2f} s: {why}", flush=True)
        self.board.stop()

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def now(self) -> float:
        """Vehicle time (s) as the companion's clock follows it."""
        return self.link.clock.now()

    def poll(self) -> None:
        """Read the link, the legs and the physics' events. A leg board the rig's own flying
        (take-off, positioning, waits) finds silent is opened afresh and the silence kept in
        :attr:`leg_silences`: on real ArduCopter under machine load the board has read silent for
        1 s during the autopilot's pre-arm phase, its physics feeding it throughout (cause not
        found). A landing's controller polls the board itself; a silence in a landing fails it."""
        self.link.poll()
        if self.legs is not None:
            try:
                self.legs.poll()
            except LegTimeout as exc:
                self.leg_silences.append((self.now, str(exc)))
                self.open_legs()
        self.read_events()

    def read_events(self) -> None:
        """Take the physics' new measurement events into :attr:`track` (real ArduCopter has no
        channel for them: its physics writes them to a file; the simulated vehicle sends them as
        NAMED_VALUE_FLOAT, which the track hears on the link)."""
        if self.autopilot == "ardupilot":
            from slopelander_sitl.ardupilot.launch import read_events

            events, self._events_at = read_events(self.vehicle.events_path, self._events_at)
            self.track.events.extend((e["name"], e["t"], e["value"]) for e in events)

    def wait_command(self, handle, what: str, wall_s: float = 10.0) -> None:
        end = time.monotonic() + wall_s
        while time.monotonic() < end and not handle.done:
            self.poll()
            time.sleep(0.002)
        if not handle.ok:
            raise RigError(f"{what}: {handle.state} (result {handle.result})")

    def fly_until(self, cond, vehicle_s: float, what: str, send=None, wall_s: float = 120.0) -> None:
        """Poll (and call ``send`` each loop) until ``cond()``; RigError after ``vehicle_s`` of
        vehicle time or ``wall_s`` of wall time."""
        t0 = self.now
        end = time.monotonic() + wall_s
        while not cond():
            if self.now - t0 > vehicle_s or time.monotonic() > end:
                raise RigError(f"the vehicle did not {what} within {vehicle_s:g} s")
            self.poll()
            if send is not None:
                send()
            time.sleep(0.001)

    def wait(self, vehicle_s: float, tick=None) -> None:
        """Let ``vehicle_s`` of vehicle time pass, polling (and calling ``tick``)."""
        t0 = self.now
        end = time.monotonic() + 60 + vehicle_s * 5
        while self.now - t0 < vehicle_s and time.monotonic() < end:
            if tick is not None:
                tick()
            else:
                self.poll()
            time.sleep(0.001)

    def cut_link(self, vehicle_s: float, tick) -> float:
        """Cut the companion's link at the relay for ``vehicle_s`` of vehicle time and call
        ``tick`` (the landing's poll) until the vehicle's clock shows it back; the wall seconds
        the companion heard nothing, which decide whether it may call the link lost."""
        if self.relay is None:
            raise RigError("no relay to cut the link at: make the rig with relay=True")
        t_cut, w0 = self.now, time.monotonic()
        self.relay.cut(vehicle_s)
        while self.now <= t_cut + vehicle_s - 0.05 and time.monotonic() - w0 < 30.0:
            tick()
            time.sleep(0.001)
        if self.now <= t_cut + vehicle_s - 0.05:
            raise RigError(f"the link did not come back within 30 s of a {vehicle_s:g} s cut")
        return time.monotonic() - w0

    def armed(self) -> bool:
        hb = self.link.last.get("HEARTBEAT")
        return bool(hb and hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    def mode(self) -> int | None:
        hb = self.link.last.get("HEARTBEAT")
        return None if hb is None else hb.custom_mode

    def height(self) -> float:
        """The newest height (m) from LOCAL_POSITION_NED: counted from home (:attr:`home_range_m`
        above the pad)."""
        return self.track.pos[-1][2] if self.track.pos else 0.0

    #: The height (m) of home, where LOCAL_POSITION_NED counts from, over the pad: add it to a
    #: height over the roof to get what a level body's rangefinder (at the body's origin) reads,
    #: to compare with a range threshold (the cut, the take-off's clear height). Home is where the
    #: vehicle's model first settled on the pad; with its legs set the body rests lower (the
    #: height is then negative). A constant here, so the rig's process does not load the model
    #: (125 MB) for it; ``tests/vehicle/test_track.py`` checks it against the vehicle's rangefinder.
    home_range_m: float = 0.148

    def surface_z(self, x: float, east: float = 0.0) -> float:
        """The surface's height (m) at north ``x`` and ``east`` (m from home): the pad, or the
        roof's plane, falling toward the scenario's ``fall_azimuth_deg`` (north by default)."""
        if x < ROOF_X_M:
            return 0.0
        fall = math.radians(float(self.scenario.get("fall_azimuth_deg", 0.0)))
        if fall == 0.0:
            return ROOF_Z_M - (x - ROOF_X_M) * math.tan(math.radians(self.slope_deg))
        across = (x - ROOF_X_M) * math.cos(fall) + east * math.sin(fall)
        return ROOF_Z_M - across * math.tan(math.radians(self.slope_deg))

    # ------------------------------------------------------------------- flying
    def pilot_stick_down_while_disarmed(self) -> None:
        """The pilot's habit, for a scenario whose pilot holds the throttle centred: the stick
        goes to the bottom while the vehicle is disarmed (ArduCopter arms only so, even for a
        companion's take-off in GUIDED: AP_Arming::rc_arm_checks) and back up once it is armed.
        Call it from the loop that polls; it sends at most twice a second."""
        now = time.monotonic()
        if self.armed():
            if self._stick_held:
                throttle_override(self.link, 0)
                self._stick_held = False
        elif now - self._stick_sent >= 0.5:
            throttle_override(self.link, THROTTLE_DOWN_US)
            self._stick_held, self._stick_sent = True, now

    def set_legs(self, up: float, down: float, vehicle_s: float = 30.0) -> None:
        op = self.legs.start_presets(up, down, tolerance_nm=0.15, timeout=vehicle_s)
        self.fly_until(lambda: op.done, vehicle_s, "set the legs")
        if op.error is not None:
            raise RigError(f"legs: {op.error}")

    def take_off(self, height_m: float = 3.0, force: bool = False) -> None:
        """GUIDED, arm (``force``: past the pre-arm lean check, e.g. on a roof) and climb to
        ``height_m`` above the pad."""
        L = self.link
        try:
            arm_in_guided(L, self.poll, force=force)
        except TimeoutError as exc:
            raise RigError(str(exc)) from None
        # the command's altitude is above home, which arming moves to where the vehicle armed
        # (AP_Arming_Copter::arm; the simulated vehicle alike): from the height above the pad
        # (LOCAL_POSITION_NED, from the origin) and the height above home (GLOBAL_POSITION_INT's,
        # newer than the arm)
        armed_at = self.now
        self.fly_until(lambda: self._above_home(newer_than=armed_at) is not None, 2.0, "report home")
        above_home = self._above_home(newer_than=armed_at)
        target = height_m - self.height() + above_home
        self.wait_command(L.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, target), "take-off")
        self.fly_until(lambda: self.height() > height_m - 0.3, 30.0, "climb")

    def _above_home(self, newer_than: float) -> float | None:
        """GLOBAL_POSITION_INT's height above home (m), when one stamped after ``newer_than``
        (vehicle s) has come."""
        gp = self.link.last.get("GLOBAL_POSITION_INT")
        if gp is None or gp.time_boot_ms / 1000.0 <= newer_than:
            return None
        return gp.relative_alt / 1000.0

    def goto(self, x: float, z: float, vehicle_s: float = 30.0, tol: float = 0.15) -> None:
        """Fly to world (x, z up) in GUIDED and stop there."""

        def send() -> None:
            self.link.conn.mav.set_position_target_local_ned_send(
                0,
                self.info.system,
                self.info.component,
                mavlink.MAV_FRAME_LOCAL_NED,
                0x0DF8,
                x,
                0,
                -z,
                0,
                0,
                0,
                0,
                0,
                0,
                0,
                0,
            )

        last = [-1.0]

        def throttled() -> None:
            if time.monotonic() - last[0] > 0.05:
                last[0] = time.monotonic()
                send()

        def there() -> bool:
            if not self.track.pos:
                return False
            _, px, pz, vx, vz = self.track.pos[-1]
            return abs(px - x) < tol and abs(pz - z) < tol and abs(vx) < 0.1 and abs(vz) < 0.1

        self.fly_until(there, vehicle_s, f"reach x={x:.2f} z={z:.2f}", send=throttled)

    def go_over_roof(self, height_m: float = 2.0, x: float = OVER_ROOF_X_M, vehicle_s: float = 60.0) -> None:
        """Hover ``height_m`` above the roof surface at world ``x`` (over the pad first if needed).

        From the pad side the vehicle climbs to the target's height if it is lower, then flies
        straight to the target unless that line passes within :data:`RIDGE_CLEARANCE_M` of the
        ridge: then it crosses level, clear of it, and descends over the target. A spot low on a
        steep roof is below the ridge (60 deg, 1 m over the surface at x = 5.5: 3.3 m below it),
        and the straight line from the pad ran into the roof: the vehicle never arrived."""
        z = self.surface_z(x) + height_m
        if self.track.pos and self.track.pos[-1][1] < ROOF_X_M:
            x0 = self.track.pos[-1][1]
            z0 = max(z, self.height())
            self.goto(x0, z0, vehicle_s)
            z_ridge = z0 + (z - z0) * (ROOF_X_M - x0) / (x - x0) if x > ROOF_X_M else z0
            if z_ridge < ROOF_Z_M + RIDGE_CLEARANCE_M:
                self.goto(x, max(z0, ROOF_Z_M + RIDGE_CLEARANCE_M), vehicle_s)
        self.goto(x, z, vehicle_s)

    def land(
        self,
        preset: tuple[float, float],
        cfg: Config | None = None,
        *,
        next_preset: tuple[float, float] | None = None,
        timeout_s: float = 120.0,
        rest_s: float = 2.0,
        lander: Lander | None = None,
        until: tuple[str, ...] = ("LANDED", "ABORTED", "ESTOP", "READY"),
        uphill_angle_deg: float | None = None,
        held_s: float | None = HELD_S,
    ) -> Flight:
        """One landing by the companion's controller (until it reaches a state in ``until``, or
        ``held_s`` of vehicle time into a hold after a slide: :data:`HELD_S`); then ``rest_s`` of
        vehicle time with the controller still running.

        ``uphill_angle_deg`` is the uphill legs' angle the landing sets (the table's, as
        ``slopelander land`` passes it); the flight keeps the angles the board reported when the
        reflex was armed (ARMED: the legs change no more after it), which the model then reads."""
        cfg = cfg or load_config()
        t0 = self.now
        lander = lander or self.session.make_lander(
            preset,
            cfg=cfg,
            next_preset=next_preset,
            slope_deg=self.slope_deg,
            uphill_angle_deg=uphill_angle_deg,
        )
        held_since: list[float] = []

        def held() -> bool:
            if held_s is None or lander.machine.name != "SETTLED":
                return False
            if "slide" not in lander.ctx.marks.get("said", set()):
                return False
            if not held_since:
                held_since.append(self.now)
            # ended only while the script is heard holding the motors: a script silent for under
            # a second still reads as its last state (CUT), SETTLED may say the slide then, and
            # once it reads silent the companion disarms by itself (Settled.without_script), which
            # the hold's end must not cut short (a dead script's landing ended SETTLED so, 1 in
            # 24). The count runs from the slide all the same: a hold past HELD_S may slide on to
            # the roof's edge, where the script gives the motors back and the companion aborts
            holding = lander.link.script_present and lander.link.script_state in MOTORS_HELD
            return holding and self.now - held_since[0] >= held_s

        start = time.monotonic()
        end = lander.run(timeout_s, until=("ARMED", *until))
        angles = self.leg_angles()
        if end not in until:
            end = lander.run(max(0.0, timeout_s - (time.monotonic() - start)), until=until, stop=held)
        if end not in ("ABORTED", "ESTOP"):
            self.wait(rest_s, tick=lander.poll)
        self.read_events()
        return Flight(
            end,
            list(lander.machine.history),
            preset,
            cfg,
            t0,
            self.track.contact(t0),
            self.track,
            lander,
            angles,
        )

    def plan(self, cfg: Config, slope_deg: float | None = None):
        """The legs for a landing on ``slope_deg`` (the roof's by default) and the impact speed they
        were chosen for, as ``slopelander land`` plans them (:meth:`Session.plan`): the lookup
        table's torques and uphill angle, checked against the board's calibration."""
        return self.session.plan(
            self.slope_deg if slope_deg is None else slope_deg, pilot_switch=False, cfg=cfg
        )

    def leg_angles(self) -> tuple[float, float]:
        """(uphill, downhill) pair means of the board's reported leg angles (deg)."""
        st = self.legs.status if self.legs is not None else None
        if st is None:
            return (37.5, 37.5)
        a = [lg.angle_deg for lg in st.legs]
        return (0.5 * (a[0] + a[1]), 0.5 * (a[2] + a[3]))

    def take_off_again(self, flight: Flight, timeout_s: float = 60.0) -> str:
        """The controller's own take-off and leg reset after a landing; returns its end state
        (LANDED when the companion refuses the take-off: ``ctx.marks["takeoff_refused"]`` says why)."""
        flight.lander.takeoff_request = True
        refused = lambda: "takeoff_refused" in flight.lander.ctx.marks  # noqa: E731
        end = flight.lander.run(timeout_s, until=("READY", "ABORTED", "ESTOP"), stop=refused)
        flight.history[:] = list(flight.lander.machine.history)
        return end
