"""``slopelander demo``: a whole simulated flight and landing on a roof, no hardware.

The simulated ArduCopter (``python -m sitl.vehicle``, running the real on-board Lua script) and
the simulated leg board (``python -m sitl.legboard``, on a pseudo-terminal) run as their own
processes; the companion's landing controller flies them through the same MAVLink endpoint and
serial path a real vehicle would use. It takes off from a level pad, flies over a roof, lands on
it with the lookup table's preset and reverse thrust, takes off again, loosens the legs so their
springs reset them, and says how the landing went. Everything it saw is written out: the MAVLink
telemetry log (``flight.tlog``, readable by pymavlink's ``mavlogdump.py``), the state transitions
(``transitions.jsonl``) and a picture of the flight (``flight.png``).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from slopelander.errors import SlopelanderError

G_MPS2 = 9.80665
#: a foot on the roof while the motors still hold the vehicle (the powered descent reads 1 g, and
#: after the cut the reading only falls): a reading this far above 1 g. The cut latency and the
#: rotors' spin-down let the uphill foot of a steep roof touch under thrust, at 1.6-1.9 g: under
#: the script's 2 g with the thrust's g in it, so the script reverses at the harder contact after
POWERED_TOUCH_MPS2 = 0.3 * G_MPS2
#: a contact began where the reading rose this far above 1 g (the descent's corrections stay under)
ONSET_MPS2 = 0.02 * G_MPS2
#: the accelerometer's low-pass (ArduPilot's two-pole Butterworth at INS_ACCEL_FILTER, 20 Hz) delays
#: a reading by sqrt(2) / (2 pi 20 Hz) = 11 ms: the velocity report before a contact is looked for
#: that much before the reading's rise
FILTER_DELAY_S = math.sqrt(2.0) / (2.0 * math.pi * 20.0)
ROOF_X_M = 3.0  # world x of the roof's top edge
ROOF_Z_M = 0.5  # its height above the pad
CRUISE_HEIGHT_M = 3.0  # take-off height above the pad
OVER_ROOF_X_M = 5.5  # where the vehicle hovers before the landing starts
APPROACH_RANGE_M = 2.0  # the height above the roof the landing starts from (within the 3 m range)


class DemoError(SlopelanderError):
    """The demo could not start or did not finish its flight."""


@dataclass
class Telemetry:
    """Time series the picture is drawn from (vehicle time, SI units)."""

    t: list[float] = field(default_factory=list)
    height: list[float] = field(default_factory=list)  # above the pad, from LOCAL_POSITION_NED
    vz_up: list[float] = field(default_factory=list)
    range_t: list[float] = field(default_factory=list)
    range_m: list[float] = field(default_factory=list)
    accel_t: list[float] = field(default_factory=list)
    accel: list[float] = field(default_factory=list)
    pitch_t: list[float] = field(default_factory=list)
    pitch_deg: list[float] = field(default_factory=list)
    servo_t: list[float] = field(default_factory=list)
    servo: list[list[int]] = field(default_factory=list)
    legs_t: list[float] = field(default_factory=list)
    leg_torque: list[list[float]] = field(default_factory=list)
    leg_angle: list[list[float]] = field(default_factory=list)
    x_t: list[float] = field(default_factory=list)
    x: list[float] = field(default_factory=list)
    legs: object = None  # the leg-board driver whose reports are sampled with the position

    def listen(self, msg: object) -> None:
        kind = msg.get_type()  # type: ignore[attr-defined]
        if kind == "LOCAL_POSITION_NED":
            t = msg.time_boot_ms / 1000.0  # type: ignore[attr-defined]
            status = getattr(self.legs, "status", None)
            if status is not None:
                self.legs_t.append(t)
                self.leg_torque.append(
                    [math.nan if s.torque_nm is None else s.torque_nm for s in status.legs]
                )
                self.leg_angle.append([s.angle_deg for s in status.legs])
            self.t.append(t)
            self.height.append(-msg.z)  # type: ignore[attr-defined]
            self.vz_up.append(-msg.vz)  # type: ignore[attr-defined]
            self.x_t.append(t)
            self.x.append(msg.x)  # type: ignore[attr-defined]
        elif kind == "DISTANCE_SENSOR":
            self.range_t.append(msg.time_boot_ms / 1000.0)  # type: ignore[attr-defined]
            self.range_m.append(msg.current_distance / 100.0)  # type: ignore[attr-defined]
        elif kind == "RAW_IMU":
            a = (msg.xacc, msg.yacc, msg.zacc)  # type: ignore[attr-defined]
            self.accel_t.append(msg.time_usec / 1e6)  # type: ignore[attr-defined]
            self.accel.append(math.sqrt(sum(v * v for v in a)) * 9.80665 / 1000.0)
        elif kind == "ATTITUDE":
            self.pitch_t.append(msg.time_boot_ms / 1000.0)  # type: ignore[attr-defined]
            self.pitch_deg.append(math.degrees(msg.pitch))  # type: ignore[attr-defined]
        elif kind == "SERVO_OUTPUT_RAW":
            self.servo_t.append(msg.time_usec / 1e6)  # type: ignore[attr-defined]
            self.servo.append([getattr(msg, f"servo{i}_raw") for i in range(1, 5)])


@dataclass
class DemoResult:
    """What a person wants to know after the flight."""

    outcome: str  # LANDED_AND_RESET, LANDED, or the state the companion stopped in
    slope_deg: float
    preset_nm: tuple[float, float]
    preset_source: str
    uphill_angle_deg: float | None  # the preset's (the table's), set on the board before the descent
    uphill_angle_measured_deg: float | None  # as the board reported it just before the cut
    expected_impact_mps: float
    impact_mps: float | None
    slide_m: float | None
    min_pitch_deg: float | None
    reflex_states: list[int]
    transitions: list[dict]
    files: dict[str, str]
    wall_s: float

    def summary(self) -> str:
        lines = [
            f"demo: {self.slope_deg:g} deg roof, legs {self.preset_nm[0]:.2f}/{self.preset_nm[1]:.2f} N*m "
            f"({self.preset_source}), expected impact {self.expected_impact_mps:.2f} m/s",
        ]
        if self.uphill_angle_deg is not None:
            measured = self.uphill_angle_measured_deg
            lines.append(
                f"uphill legs: preset {self.uphill_angle_deg:.1f} deg, board reported "
                + ("nothing" if measured is None else f"{measured:.1f} deg")
                + " before the cut"
            )
        for h in self.transitions:
            lines.append(f"  {h['t']:8.2f} s  {h['from'] or '-':>9} -> {h['to']:<9} {h['reason']}")
        if self.impact_mps is not None:
            lines.append(
                f"impact {self.impact_mps:.2f} m/s down; moved {self.slide_m:.2f} m downhill after it; "
                f"lowest pitch {self.min_pitch_deg:.0f} deg"
            )
        lines.append(f"outcome: {self.outcome}  ({self.wall_s:.0f} s wall)")
        lines += [f"{k}: {v}" for k, v in self.files.items()]
        return "\n".join(lines)


def check_out_dir(out: Path) -> None:
    """Refuse an output folder that cannot be written before any process starts."""
    if out.exists() and not out.is_dir():
        raise DemoError(f"--out {out} is a file; give a folder")
    parent = out if out.exists() else out.parent
    if not parent.exists():
        raise DemoError(f"--out {out}: folder {parent} does not exist (create it first)")
    if not os.access(parent, os.W_OK):
        raise DemoError(f"--out {out}: folder {parent} is not writable")


def _wait(link, handle, seconds: float, what: str) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end and not handle.done:
        link.poll()
        time.sleep(0.002)
    if not handle.ok:
        raise DemoError(f"{what}: {handle.describe()}")


def _fly_until(link, cond, seconds: float, what: str, send=None) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        link.poll()
        if send is not None:
            send()
        if cond():
            return
        time.sleep(0.002)
    raise DemoError(f"the vehicle did not {what} within {seconds:g} s")


def run_demo(
    out: Path = Path("slopelander-demo"),
    slope_deg: float = 35.0,
    speed: float = 2.0,
    table: Path | None = None,
    plot: bool = True,
    echo=print,
    autopilot: str = "sim",
    arducopter: str | Path | None = None,
) -> DemoResult:
    """Fly the whole demo; ``speed`` is simulated seconds per wall second. ``autopilot`` is
    ``"sim"`` (the project's simulated ArduCopter) or ``"ardupilot"``: real ArduCopter SITL
    (``arducopter``, else ``$SLOPELANDER_ARDUCOPTER``) behind the same physics, in a loopback-only
    network namespace; ``speed`` is then its ``--speedup`` (it runs in lock-step with the physics,
    so a busy machine only slows it)."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    from sitl.guided import arm_in_guided
    from sitl.legs_clock import open_legs
    from sitl.vehicle.launch import start_legboard, start_vehicle
    from slopelander.controller.config import load_config
    from slopelander.controller.landing import cut_dynamics, leg_geometry, plan_landing
    from slopelander.controller.link import Link
    from slopelander.controller.runner import Lander
    from slopelander.controller.slope_estimate import SurfaceTrack
    from slopelander.controller.survey import measure_slope
    from slopelander.controller.table import LookupTable
    from slopelander.legs.calibration import load_calibration

    if not (math.isfinite(slope_deg) and 0.0 <= slope_deg <= 60.0):
        raise DemoError(f"--slope must lie within 0..60 deg, got {slope_deg:g}")
    if not (math.isfinite(speed) and 0.1 <= speed <= 20.0):
        raise DemoError(f"--speed must lie within 0.1..20, got {speed:g}")
    if autopilot not in ("sim", "ardupilot"):
        raise DemoError(f"--autopilot must be sim or ardupilot, not {autopilot!r}")
    binary = None
    if autopilot == "ardupilot":
        from sitl.ardupilot import arducopter_binary
        from sitl.launching import LaunchError

        try:
            binary = arducopter_binary(arducopter)
        except LaunchError as exc:
            raise DemoError(str(exc)) from None
    check_out_dir(out)
    out.mkdir(exist_ok=True)
    from slopelander.controller.table import DEFAULT_TABLE

    table_path = table or DEFAULT_TABLE
    lookup = LookupTable.load(table_path)
    cfg = load_config()
    calibration = load_calibration()
    preset, expected = plan_landing(
        cfg["descent.rate_mps"],
        cfg["reflex.cut_height_m"],
        slope_deg,
        leg_geometry(),
        lookup,
        None,
        calibration,
        cut_dynamics(cfg["reflex.cut_latency_s"]),
    )
    up, down, source = preset.tau_up, preset.tau_down, preset.source
    files = {"telemetry log": str(out / "flight.tlog"), "transitions": str(out / "transitions.jsonl")}
    wall0 = time.monotonic()
    scenario = {"slope_deg": float(slope_deg), "roof_x": ROOF_X_M, "roof_z": ROOF_Z_M, "start_on": "pad"}
    what = "real ArduCopter SITL" if autopilot == "ardupilot" else "the simulated vehicle"
    echo(
        f"starting the simulated leg board and {what} ({speed:g}x real time at most; the first run "
        "after an install compiles the model, about half a minute) ..."
    )
    board = start_legboard(speed=speed, clock="external")
    vehicle = None
    link = None
    legs = None
    legs_uphill: tuple[int, ...] = (0, 1)
    tele = Telemetry()
    slope_drawn = None
    try:
        if autopilot == "ardupilot":
            from sitl.ardupilot import start_arducopter

            vehicle = start_arducopter(scenario=scenario, legs=board.control, binary=binary, speedup=speed)
        else:
            vehicle = start_vehicle(
                scenario=scenario, speed=speed, lockstep=True, legboard_control=board.control
            )
        link = Link(vehicle.mavlink_url, link_loss_s=cfg["link.link_loss_s"])
        link.conn.setup_logfile(str(out / "flight.tlog"), mode="wb")
        link.add_listener(tele.listen)
        track = SurfaceTrack(cfg["slope.pair_window_s"])  # the rangefinder's points, as `land` keeps them
        link.add_listener(track.feed)
        info = link.wait_autopilot(timeout_s=30.0)
        echo(f"autopilot: {info.describe()}")
        for msg_id, hz in (
            (mavlink.MAVLINK_MSG_ID_RAW_IMU, cfg["link.imu_hz"]),
            (mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR, cfg["link.range_hz"]),
            (mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 50),
            (mavlink.MAVLINK_MSG_ID_ATTITUDE, 50),
            (mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW, 50),
        ):
            _wait(link, link.request_stream(msg_id, hz), 5, f"stream {msg_id}")
        legs = open_legs(board.pty, link, calibration=calibration)  # on the vehicle's clock
        legs_uphill = legs.pairs.uphill
        tele.legs = legs

        echo(f"take-off from the pad to {CRUISE_HEIGHT_M:g} m, then over the {slope_deg:g} deg roof")
        try:
            # ArduCopter arms in GUIDED once its EKF has an origin (20-40 s of vehicle time)
            arm_in_guided(link, lambda: (link.poll(), legs.poll()), wall_s=120 / speed + 60)
        except TimeoutError as exc:
            raise DemoError(str(exc)) from None
        _wait(
            link, link.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, CRUISE_HEIGHT_M), 5, "take-off"
        )
        _fly_until(
            link,
            lambda: bool(tele.height) and tele.height[-1] > CRUISE_HEIGHT_M - 0.3,
            60 / speed + 20,
            "climb",
        )

        def goto(height: float):
            def send() -> None:
                link.conn.mav.set_position_target_local_ned_send(
                    0,
                    info.system,
                    info.component,
                    mavlink.MAV_FRAME_LOCAL_NED,
                    0x0DF8,
                    OVER_ROOF_X_M,
                    0,
                    -height,
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                )

            return send

        def over_roof_at(height: float) -> bool:
            return (
                bool(tele.x)
                and abs(tele.x[-1] - OVER_ROOF_X_M) < 0.15
                and abs(tele.height[-1] - height) < 0.3
            )

        _fly_until(
            link,
            lambda: over_roof_at(CRUISE_HEIGHT_M),
            60 / speed + 30,
            "reach the roof",
            send=goto(CRUISE_HEIGHT_M),
        )
        # then straight down until the rangefinder (3 m at most, like the real one) sees the roof
        roof_below = ROOF_Z_M - (OVER_ROOF_X_M - ROOF_X_M) * math.tan(math.radians(slope_deg))
        approach = min(CRUISE_HEIGHT_M, roof_below + APPROACH_RANGE_M)
        _fly_until(
            link,
            lambda: over_roof_at(approach),
            60 / speed + 30,
            f"come down to {APPROACH_RANGE_M:g} m above the roof",
            send=goto(approach),
        )

        # the slope measured as `slopelander land` does (a survey pass when the approach saw too
        # little), for the picture and slope_estimate.json; the landing uses the demo's slope
        survey_t0 = link.clock.now()
        estimate, took = measure_slope(
            link, cfg, track, tick=lambda: (link.poll(), legs.poll()), note=echo, wall_s=120 / speed + 60
        )
        slope_drawn = {
            "record": estimate.record(),
            "survey": (survey_t0, survey_t0 + took) if took else None,
            "true_slope_deg": float(slope_deg),
        }
        echo(f"slope measured: {estimate.describe()}" + (f" (survey pass {took:.1f} s)" if took else ""))
        (out / "slope_estimate.json").write_text(json.dumps({**slope_drawn, "survey_s": took}, indent=1))
        files["slope estimate"] = str(out / "slope_estimate.json")
        echo(
            f"landing: legs {up:.2f}/{down:.2f} N*m from the {source}, descent "
            f"{cfg['descent.rate_mps']:g} m/s, motors stopped at {cfg['reflex.cut_height_m']:g} m, "
            f"reverse thrust {cfg['reflex.reverse_thrust_pct']:g} %"
        )
        with (out / "transitions.jsonl").open("w") as rec:
            lander = Lander(
                link,
                cfg,
                (up, down),
                legs=legs,
                record=rec,
                next_preset=(up, down),
                uphill_angle_deg=preset.angle_up_deg,
                slope_deg=slope_deg,
            )
            end = lander.run(120 / speed + 60)
            if end == "LANDED":
                t_landed = link.clock.now()
                _fly_until(
                    link,
                    lambda: lander.poll() == "LANDED" and link.clock.now() - t_landed > 2.0,
                    10 / speed + 10,
                    "rest on the roof",
                )
                echo("take-off again; loosening the legs once clear of the roof")
                lander.takeoff_request = True
                end = lander.run(60 / speed + 30, until=("READY", "ABORTED", "ESTOP"))
                if end == "READY":  # watch the legs spring back for a moment
                    t_ready = link.clock.now()
                    _fly_until(
                        link,
                        lambda: lander.poll() is not None and link.clock.now() - t_ready > 3.0,
                        10 / speed + 10,
                        "hover after the reset",
                    )
        result_state = {"READY": "LANDED_AND_RESET"}.get(end, end)
        history = list(lander.machine.history)
    finally:
        if legs is not None:
            legs.close()
        if link is not None:
            link.close()
        if vehicle is not None:
            vehicle.stop()
        board.stop()

    impact, slide, min_pitch = _landing_figures(tele, history, cfg["reflex.impact_threshold_mps2"])
    angle_measured = _uphill_angle_before_cut(tele, history, legs_uphill)
    if plot:
        from slopelander.plots.flight import plot_flight

        files["picture"] = str(
            plot_flight(
                tele,
                history,
                out / "flight.png",
                title=(
                    f"slopelander demo: {slope_deg:g} deg roof, legs {up:.2f}/{down:.2f} N*m, "
                    f"reverse thrust {cfg['reflex.reverse_thrust_pct']:g} % - {result_state}"
                ),
                slope=slope_drawn,
            )
        )
    result = DemoResult(
        result_state,
        slope_deg,
        (up, down),
        source,
        preset.angle_up_deg,
        angle_measured,
        expected,
        impact,
        slide,
        min_pitch,
        [],
        history,
        files,
        time.monotonic() - wall0,
    )
    (out / "result.json").write_text(json.dumps(asdict(result), indent=1))
    files["result"] = str(out / "result.json")
    return result


def _uphill_angle_before_cut(tele: Telemetry, history: list[dict], uphill: tuple[int, ...]) -> float | None:
    """The uphill legs' mean angle in the board's last report before the cut."""
    t_cut = next((h["t"] for h in history if h["to"] == "CUT"), None)
    if t_cut is None:
        return None
    before = [a for t, a in zip(tele.legs_t, tele.leg_angle, strict=True) if t < t_cut]
    if not before:
        return None
    return sum(before[-1][i] for i in uphill) / len(uphill)


def first_contact_speed(
    tele: Telemetry,
    t_from: float,
    t_to: float,
    spike_mps2: float,
    t_impact: float | None = None,
    t_cut: float | None = None,
) -> float | None:
    """Vertical speed (m/s, down) at the first foot contact, the first accelerometer reading
    between ``t_from`` and ``t_to`` (vehicle time) that the script's impact rule calls one: above
    ``spike_mps2``, or above the lowest reading since ``t_cut`` (the motors' cut; default
    ``t_from``) by ``spike_mps2`` less 1 g (docs/onboard-script.md), or ``POWERED_TOUCH_MPS2``
    above 1 g at any time: a foot on the roof under power (the uphill foot of a steep roof can
    touch before the thrust has gone, at 1.6-1.9 g, and the script reverses at the harder contact
    that follows). With ``t_impact``, the on-board
    script's impact (the companion's REVERSE): a first touch whose 50 Hz RAW_IMU samples all stayed
    under ``spike_mps2`` (the script reads every IMU sample, the telemetry a few) is still the
    contact, found as the highest reading above 1 g in the 50 ms up to it; without this a later,
    harder second contact was measured instead.

    The velocity is reported at 50 Hz, too seldom for a fall: from the last report before the
    contact the speed is carried on with the accelerometer, ``g - |a|`` per sample (free fall reads
    0 g), up to where the reading first rose above 1 g, the start of the contact. This is the
    speed the model and the table call the impact speed; a faster descent after it (the vehicle
    pivoting onto its downhill foot) belongs to the landing, not to its start."""
    acc = list(zip(tele.accel_t, tele.accel, strict=True))
    last = t_to if t_impact is None else min(t_to, t_impact)

    from slopelander.controller.impact import ImpactDetector

    def first_impact(until: float) -> int | None:
        detector = ImpactDetector(spike_mps2)  # the script's rule, from the cut
        after_cut = max(t_from, t_cut) if t_cut is not None else t_from
        detector.arm_after_cut(math.nextafter(after_cut, -math.inf))
        for k, (t, a) in enumerate(acc):
            if t > until:
                return None
            if t < t_from:
                continue
            if a > G_MPS2 + POWERED_TOUCH_MPS2:  # a foot on the roof, the thrust still on or not
                return k
            if t >= after_cut and detector.feed(t, 0.0, 0.0, a) is not None:
                return k
        return None

    spike = first_impact(last)
    if spike is None and t_impact is not None:
        near = [k for k, (t, a) in enumerate(acc) if t_impact - 0.05 <= t <= t_impact and a > G_MPS2]
        spike = max(near, key=lambda k: acc[k][1]) if near else None
    if spike is None and t_impact is not None:
        spike = first_impact(t_to)
    if spike is None:
        return None
    onset = spike
    while onset > 0 and acc[onset - 1][1] > G_MPS2 + ONSET_MPS2 and acc[onset - 1][0] >= t_from:
        onset -= 1
    t_onset = acc[onset][0]
    # the filtered reading rises a filter's delay after the contact: the speed is taken before it
    before = [(t, -v) for t, v in zip(tele.t, tele.vz_up, strict=True) if t <= t_onset - FILTER_DELAY_S]
    if not before:
        return None
    t_prev, speed = before[-1]
    for t, a in acc[:onset]:
        if t > t_prev:
            speed += (G_MPS2 - a) * (t - t_prev)
            t_prev = t
    return speed


def _landing_figures(
    tele: Telemetry, history: list[dict], spike_mps2: float
) -> tuple[float | None, float | None, float | None]:
    """Impact speed (at the first contact), slide along the roof after the cut, lowest pitch
    while on the roof: read from the vehicle's own telemetry."""
    times = {h["to"]: h["t"] for h in history}
    t_cut, t_landed, t_armed = times.get("CUT"), times.get("LANDED"), times.get("ARMED")
    if t_cut is None or t_landed is None or t_armed is None:
        return None, None, None
    impact = first_contact_speed(tele, t_armed, t_landed, spike_mps2, times.get("REVERSE"), t_cut)
    xs = [x for t, x in zip(tele.x_t, tele.x, strict=True) if t_cut + 0.05 <= t <= t_landed]
    slide = (max(xs) - min(xs)) if xs else None
    pitches = [p for t, p in zip(tele.pitch_t, tele.pitch_deg, strict=True) if t_cut <= t <= t_landed]
    return impact, slide, (min(pitches) if pitches else None)
