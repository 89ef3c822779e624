"""``slopelander demo``: the main job, a whole simulated flight and landing (no hardware)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo",
        help="fly a whole simulated landing on a roof (vehicle, on-board script and legs as processes)",
        description="Start the simulated ArduCopter (with the on-board script) and the simulated leg "
        "board as processes, take off, fly over a roof, land with the lookup table's preset and "
        "reverse thrust, take off again and reset the legs. Writes a telemetry log, the state "
        "transitions and a picture of the flight.",
    )
    p.add_argument("--slope", type=float, default=35.0, help="roof slope, deg (0..60)")
    p.add_argument("--speed", type=float, default=2.0, help="simulated seconds per wall second")
    p.add_argument("--table", type=Path, default=None, help="lookup table (default: the shipped one)")
    p.add_argument("--out", type=Path, default=Path("slopelander-demo"), help="output folder")
    p.add_argument("--no-plot", action="store_true", help="skip the picture")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from slopelander.demo import run_demo

    result = run_demo(
        out=args.out, slope_deg=args.slope, speed=args.speed, table=args.table, plot=not args.no_plot
    )
    print(result.summary())
    return 0 if result.outcome == "LANDED_AND_RESET" else 3
