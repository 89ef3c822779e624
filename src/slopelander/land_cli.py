"""``slopelander land``: one landing on a real (or simulated) vehicle from the companion."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from slopelander.errors import SlopelanderError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("land", help="land on a slope: preset the legs, descend, reflex, disarm")
    p.add_argument("--connect", required=True, help="MAVLink connection string, e.g. udpin:0.0.0.0:14550")
    p.add_argument("--legs", required=True, help="leg board serial port, e.g. /dev/ttyACM1")
    p.add_argument("--slope", required=True, type=float, help="slope of the landing site, deg (0..89)")
    p.add_argument("--table", help="lookup table file (YAML); default: the shipped table")
    p.add_argument("--config", help="controller settings overriding the shipped defaults")
    p.add_argument(
        "--record", default="landing.jsonl", help="transitions as JSON lines (default landing.jsonl)"
    )
    p.add_argument(
        "--timeout", type=float, default=120.0, help="give up (abort) after this many s (default 120)"
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from slopelander.controller.config import load_config
    from slopelander.controller.landing import (
        angle_instruction,
        cut_dynamics,
        leg_geometry,
        plan_landing,
    )
    from slopelander.controller.link import LANDING_MESSAGES, Link
    from slopelander.controller.rc_presets import preset_for
    from slopelander.controller.runner import Lander
    from slopelander.controller.table import LookupTable
    from slopelander.legs.calibration import load_calibration
    from slopelander.legs.driver import LegBoard

    if not (math.isfinite(args.slope) and 0 <= args.slope < 90):
        raise SlopelanderError(f"--slope must be within 0..89 deg, got {args.slope:g}")
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        raise SlopelanderError(f"--timeout must be a positive number of seconds, got {args.timeout:g}")
    cfg = load_config(args.config)
    from slopelander.controller.table import DEFAULT_TABLE

    table = LookupTable.load(args.table or DEFAULT_TABLE)
    calibration = load_calibration()
    link = Link(args.connect, link_loss_s=cfg["link.link_loss_s"], decode=LANDING_MESSAGES)
    legs = None
    try:
        info = link.wait_autopilot(timeout_s=10.0)
        print(f"autopilot: {info.describe()}")
        link.request_stream(27, cfg["link.imu_hz"])  # RAW_IMU
        link.request_stream(132, cfg["link.range_hz"])  # DISTANCE_SENSOR
        link.request_stream(65, 10)  # RC_CHANNELS
        link.request_stream(32, cfg["link.position_hz"])  # LOCAL_POSITION_NED
        link.request_stream(30, cfg["link.attitude_hz"])  # ATTITUDE
        preset, speed = plan_landing(
            cfg["descent.rate_mps"],
            cfg["reflex.cut_height_m"],
            args.slope,
            leg_geometry(),
            table,
            preset_for(cfg, link.last.get("RC_CHANNELS")),
            calibration,
            cut_dynamics(cfg["reflex.cut_latency_s"]),
        )
        up, down = preset.tau_up, preset.tau_down
        angle = "" if preset.angle_up_deg is None else f", uphill angle {preset.angle_up_deg:.1f} deg"
        print(
            f"expected impact {speed:.2f} m/s on {args.slope:g} deg; "
            f"legs {up:.2f}/{down:.2f} N*m{angle} ({preset.source})"
        )
        legs = LegBoard.open(args.legs, calibration=calibration)
        todo = angle_instruction(preset.angle_up_deg, legs.info.angle_stop)
        if todo is not None:
            print(todo)
            link.send_statustext(f"SL set uphill legs to {preset.angle_up_deg:.1f} deg")
        with Path(args.record).open("w") as rec:
            lander = Lander(
                link,
                cfg,
                (up, down),
                legs=legs,
                record=rec,
                uphill_angle_deg=preset.angle_up_deg,
                slope_deg=args.slope,
            )
            end = lander.run(args.timeout)
        for h in lander.machine.history:
            print(f"{h['t']:9.3f} s  {h['from'] or '-':>9} -> {h['to']:<9} {h['reason']}")
        print(f"outcome: {end}")
        return 0 if end == "LANDED" else 3
    finally:
        if legs is not None:
            legs.close()
        link.close()
