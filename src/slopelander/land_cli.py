"""``slopelander land``: one landing on a real (or simulated) vehicle from the companion.

Every argument is checked before the autopilot is contacted: the connection string's form, the
slope against the lookup table, the output file, the calibration, and the leg board itself (it is
opened once and asked what it is: a real board flies only with a measured calibration). The state
changes are printed as they happen.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import sys
from pathlib import Path
from typing import IO

from slopelander.errors import SlopelanderError
from slopelander.outputs import check_output

NETWORK_SCHEMES = ("tcp", "tcpin", "udp", "udpin", "udpout", "udpbcast")
"""pymavlink's network connection strings (``mavutil.mavlink_connection``): SCHEME:HOST:PORT."""

CONNECT_FORMS = (
    "tcp:HOST:PORT, tcpin:HOST:PORT, udpin:HOST:PORT, udpout:HOST:PORT, udpbcast:HOST:PORT, "
    "udp:HOST:PORT (= udpin), or a serial device such as /dev/ttyACM0 (with --baud)"
)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("land", help="land on a slope: preset the legs, descend, reflex, disarm")
    p.add_argument(
        "--connect",
        required=True,
        help="MAVLink connection: tcp:HOST:PORT, tcpin:HOST:PORT, udpin:HOST:PORT, udpout:HOST:PORT "
        "or a serial device (/dev/ttyACM0, with --baud)",
    )
    p.add_argument("--baud", type=int, help="baud rate of a serial --connect device (default 115200)")
    p.add_argument("--legs", required=True, help="leg board serial port, e.g. /dev/ttyACM1")
    p.add_argument(
        "--slope",
        required=True,
        type=slope_arg,
        help="slope of the landing site, deg (within the lookup table's slopes: 0..60 for the shipped one), "
        "checked against the slope the companion measures; or 'auto': land on the measured slope "
        "(docs/slope-estimate.md)",
    )
    p.add_argument("--table", help="lookup table file (YAML); default: the shipped table")
    p.add_argument("--config", help="controller settings overriding the shipped defaults")
    p.add_argument(
        "--calibration",
        metavar="FILE",
        help="the leg board's measured current-to-torque calibration (YAML, docs/leg-protocol.md); "
        "required for a real board, the simulated board may fly the shipped assumed curve",
    )
    p.add_argument("--record", metavar="FILE", help="also write the state changes here, as JSON lines")
    p.add_argument(
        "--timeout", type=float, default=120.0, help="give up (abort) after this many s (default 120)"
    )
    p.set_defaults(handler=run)


def slope_arg(text: str) -> float | str:
    """``--slope``: 'auto' or a number of degrees (range-checked in :func:`run`)."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of degrees or 'auto', got {text!r}") from None


def connection_string(text: str, baud: int | None) -> str:
    """The pymavlink string for ``--connect``/``--baud``, or a one-line error naming the forms."""
    text = text.strip()
    bad = SlopelanderError(f"--connect {text!r} is not a MAVLink connection; use {CONNECT_FORMS}")
    scheme, _, rest = text.partition(":")
    if scheme in NETWORK_SCHEMES or re.fullmatch(r"[\w.-]+:\d+", text):
        host, _, port = (rest if scheme in NETWORK_SCHEMES else text).rpartition(":")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise bad
        if baud is not None:
            raise SlopelanderError(f"--baud is for a serial device, not for --connect {text}")
        return text
    device, comma, rate = text.partition(",")
    if not (device.startswith("/dev/") or re.fullmatch(r"COM\d+", device, re.IGNORECASE)):
        raise bad
    if comma and (not rate.isdigit() or baud is not None):
        raise SlopelanderError(f"--connect {text!r}: give the baud rate with --baud only")
    speed = baud if baud is not None else int(rate) if comma else None
    if speed is not None and speed <= 0:
        raise SlopelanderError(f"--baud must be a positive number, got {speed}")
    if device.startswith("/dev/") and not Path(device).exists():
        raise SlopelanderError(f"--connect {device}: no such device")
    return device if speed is None else f"{device},{speed}"


class LiveTransitions:
    """Where the state machine writes each transition (a JSON line): printed at once, and copied
    to the ``--record`` file when there is one."""

    def __init__(self, record: IO[str] | None = None, out: IO[str] | None = None) -> None:
        self.record = record
        self.out = out or sys.stdout

    def write(self, text: str) -> int:
        if self.record is not None:
            self.record.write(text)
        for line in text.splitlines():
            with_keys = json.loads(line) if line.strip() else {}
            if "to" in with_keys:
                print(format_transition(with_keys), file=self.out, flush=True)
        return len(text)

    def flush(self) -> None:
        if self.record is not None:
            self.record.flush()


def format_transition(h: dict) -> str:
    return f"{h['t']:9.3f} s  {h['from'] or '-':>9} -> {h['to']:<9} {h['reason']}"


def run(args: argparse.Namespace) -> int:
    auto = args.slope == "auto"
    if not auto and not (math.isfinite(args.slope) and 0 <= args.slope < 90):
        raise SlopelanderError(f"--slope must be within 0..89 deg, got {args.slope:g}")
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        raise SlopelanderError(f"--timeout must be a positive number of seconds, got {args.timeout:g}")
    url = connection_string(args.connect, args.baud)
    check_output(args.record, "--record")

    from slopelander.controller.config import load_config
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable
    from slopelander.legs.calibration import load_calibration
    from slopelander.legs.driver import LegBoard

    cfg = load_config(args.config)
    table = LookupTable.load(args.table or DEFAULT_TABLE)
    lo, hi = table.slope_range
    if not auto and not lo <= args.slope <= hi:
        raise SlopelanderError(
            f"--slope {args.slope:g} is outside the lookup table's slopes {lo:g}..{hi:g} deg "
            f"({args.table or 'the shipped table'})"
        )
    if "://" not in args.legs and not Path(args.legs).exists():  # pyserial also takes URLs
        raise SlopelanderError(f"--legs {args.legs}: no such device (is the leg board plugged in?)")
    calibration = load_calibration(args.calibration)
    with LegBoard.open(args.legs, calibration=calibration) as probe:  # what board is it?
        simulated = probe.info is not None and probe.info.simulated
    if not simulated and (args.calibration is None or calibration.assumed):
        why = "no --calibration given" if args.calibration is None else f"{args.calibration} is assumed"
        raise SlopelanderError(
            f"a real leg board flies only with a measured calibration ({why}): "
            "measure the current-to-torque curve and pass it with --calibration FILE"
        )
    if calibration.assumed:
        print(f"(simulated leg board: torques through the ASSUMED calibration {calibration.source})")
    return _fly(args, url, cfg, table, calibration)


def _fly(args: argparse.Namespace, url: str, cfg, table, calibration) -> int:
    from slopelander.controller.landing import (
        angle_instruction,
        cut_dynamics,
        leg_geometry,
        plan_landing,
    )
    from slopelander.controller.link import LANDING_MESSAGES, Link
    from slopelander.controller.rc_presets import preset_for
    from slopelander.controller.runner import Lander
    from slopelander.controller.slope_estimate import SurfaceTrack
    from slopelander.legs.driver import LegBoard

    link = Link(url, link_loss_s=cfg["link.link_loss_s"], decode=LANDING_MESSAGES)
    track = SurfaceTrack(cfg["slope.pair_window_s"])
    link.add_listener(track.feed)
    legs = None
    rec = None
    try:
        info = link.wait_autopilot(timeout_s=cfg["link.heartbeat_wait_s"])
        print(f"autopilot: {info.describe()}")
        link.request_stream(27, cfg["link.imu_hz"])  # RAW_IMU
        link.request_stream(132, cfg["link.range_hz"])  # DISTANCE_SENSOR
        link.request_stream(65, 10)  # RC_CHANNELS
        link.request_stream(32, cfg["link.position_hz"])  # LOCAL_POSITION_NED
        link.request_stream(30, cfg["link.attitude_hz"])  # ATTITUDE
        rec = Path(args.record).open("w") if args.record else None  # noqa: SIM115 (closed below)
        slope, est, bound = measured_slope(args.slope, link, cfg, table, track, rec)
        if slope is None:
            return 3
        preset, speed = plan_landing(
            cfg["descent.rate_mps"],
            cfg["reflex.cut_height_m"],
            slope,
            leg_geometry(),
            table,
            preset_for(cfg, link.last.get("RC_CHANNELS")),
            calibration,
            cut_dynamics(cfg["reflex.cut_latency_s"]),
        )
        up, down = preset.tau_up, preset.tau_down
        angle = "" if preset.angle_up_deg is None else f", uphill angle {preset.angle_up_deg:.1f} deg"
        print(
            f"expected impact {speed:.2f} m/s on {slope:.1f} deg; "
            f"legs {up:.2f}/{down:.2f} N*m{angle} ({preset.source})"
        )
        legs = LegBoard.open(args.legs, calibration=calibration)
        todo = angle_instruction(preset.angle_up_deg, legs.info.angle_stop)
        if todo is not None:
            print(todo)
            link.send_statustext(f"SL set uphill legs to {preset.angle_up_deg:.1f} deg")
        lander = Lander(
            link,
            cfg,
            (up, down),
            legs=legs,
            record=LiveTransitions(rec),
            uphill_angle_deg=preset.angle_up_deg,
            slope_deg=slope,
            slope_estimate=est,
            slope_bound_deg=bound,
        )
        with PilotInterrupts(lander) as interrupts:
            end = lander.run(args.timeout, interrupts=interrupts)
        left = link.settle()
        if left:
            print(f"warning: {left} command(s) to the autopilot unanswered at exit", flush=True)
        if end == "SETTLED":  # ended on the roof, armed, motors held: said, not hidden
            print(
                "the vehicle is ARMED on the roof with its motors held stopped by the on-board script; "
                "it disarms itself once still (the companion is silent now): stay clear",
                flush=True,
            )
        print(f"outcome: {end}", flush=True)
        if args.record:
            print(f"transitions: {args.record}")
        return 0 if end == "LANDED" else 3
    finally:
        if rec is not None:
            rec.close()
        if legs is not None:
            legs.close()
        link.close()


class PilotInterrupts:
    """Ctrl-C (SIGINT) and SIGTERM during a landing are counted, not raised: what an interrupt
    does depends on the landing's state (:meth:`slopelander.controller.runner.Lander.interrupt`),
    and a KeyboardInterrupt thrown out of the middle of a step would leave the vehicle wherever
    it was. Each one is answered with a line saying what happens now."""

    def __init__(self, lander) -> None:
        self.lander = lander
        self.count = 0
        self._old: dict[int, object] = {}

    def _on_signal(self, signum: int, frame: object) -> None:
        self.count += 1
        state = self.lander.machine.name if self.lander.machine._started else "PRESET"
        if state in ("CUT", "REVERSE", "SETTLED") and self.count == 1:
            what = "on the roof with the motors held: finishing the landing to its disarm (again to leave)"
        elif state in ("CUT", "REVERSE", "SETTLED"):
            what = "leaving the vehicle to the on-board script, which disarms it once still"
        elif state in ("LANDED", "READY", "ABORTED", "ESTOP"):
            what = "ending"
        else:
            what = "aborting the landing: the autopilot holds position in LOITER"
        print(f"interrupted in {state}: {what}", flush=True)

    def __call__(self) -> int:
        return self.count

    def __enter__(self) -> PilotInterrupts:
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._old[sig] = signal.signal(sig, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


def measured_slope(
    pilot, link, cfg, table, track, rec: IO[str] | None
) -> tuple[float | None, object, float | None]:
    """The slope to land on, the estimate and the bound (deg) for CHECKS: with ``--slope auto``
    the measured slope (None, after printing and recording why, when it cannot be trusted); with
    a number, that number, checked in CHECKS against the estimate (unless ``slope.check_pilot``
    is false: then no survey and no check)."""
    import numpy as np

    from slopelander.controller.slope_estimate import check_bound, slope_to_land
    from slopelander.controller.survey import measure_slope

    auto = pilot == "auto"
    if not auto and not cfg["slope.check_pilot"]:
        return float(pilot), None, None
    est, took = measure_slope(link, cfg, track)
    cell = float(max(np.diff(table.slopes))) if len(table.slopes) > 1 else 0.0
    bound = check_bound(cell, est.sigma_deg or 0.0, cfg["slope.check_sigmas"], cfg["slope.check_bound_deg"])
    print(f"slope measured: {est.describe()}" + (f" (survey pass {took:.1f} s)" if took else ""), flush=True)
    if not auto:
        return float(pilot), est, bound
    slope, why = slope_to_land(est, bound)
    lo, hi = table.slope_range
    if slope is not None and not lo <= slope <= hi:
        slope, why = None, f"measured slope {slope:.1f} deg is outside the lookup table's {lo:g}..{hi:g} deg"
    if slope is None:
        print(f"refused: {why}", flush=True)
        if rec is not None:
            rec.write(json.dumps({"slope_estimate": est.record(), "bound_deg": bound, "refused": why}) + "\n")
        link.send_statustext(f"SL refused: {why}"[:50])
    return slope, est, bound
