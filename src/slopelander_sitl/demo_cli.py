"""``slopelander demo``: the main job, a whole simulated flight and landing (no hardware)."""

from __future__ import annotations

import argparse
from pathlib import Path

from slopelander.outputs import check_output_dir


class _RenamedSpeed(argparse.Action):
    """``demo --speed`` was the simulation rate, while ``--speed`` is the impact speed in
    ``simulate`` and ``lookup``: refused with the new name rather than read two ways."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:  # type: ignore[override]
        parser.error(
            f"--speed {values}: the simulation rate is now --time-scale {values} (simulated seconds per "
            "wall second); the impact speed of the demo follows from --slope and the lookup table"
        )


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo",
        help="fly a whole simulated landing on a roof (vehicle, on-board script and legs as processes)",
        description="Start the simulated ArduCopter (with the on-board script) and the simulated leg "
        "board as processes, take off, fly over a roof, land with the lookup table's preset and "
        "reverse thrust, take off again and reset the legs. Writes a telemetry log, the state "
        "transitions and a picture of the flight. Exit codes: 0 landed and reset, 1 an error, 2 a "
        "usage error, 3 the flight did not end landed and reset, 130 interrupted.",
    )
    p.add_argument("--slope", type=float, default=35.0, help="roof slope, deg (0..60)")
    p.add_argument(
        "--time-scale", type=float, default=2.0, metavar="X", help="simulated seconds per wall second"
    )
    p.add_argument("--speed", action=_RenamedSpeed, help=argparse.SUPPRESS)
    p.add_argument("--table", type=Path, default=None, help="lookup table (default: the shipped one)")
    p.add_argument("--out", type=Path, default=Path("slopelander-demo"), help="output folder")
    p.add_argument("--no-plot", action="store_true", help="skip the picture")
    p.add_argument(
        "--autopilot",
        choices=("sim", "ardupilot"),
        default="sim",
        help="sim: the project's simulated ArduCopter (default); ardupilot: real ArduCopter SITL behind "
        "the same physics, in a loopback-only network namespace (needs --arducopter or "
        "SLOPELANDER_ARDUCOPTER)",
    )
    p.add_argument(
        "--arducopter",
        type=Path,
        default=None,
        metavar="PATH",
        help="the arducopter SITL binary (./waf configure --board sitl && ./waf copter)",
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_output_dir(args.out, "--out")
    from slopelander_sitl.demo import run_demo

    if args.autopilot == "ardupilot":  # a missing binary is said before anything starts
        from slopelander_sitl.ardupilot import arducopter_binary
        from slopelander_sitl.launching import LaunchError

        try:
            arducopter_binary(args.arducopter)
        except LaunchError as exc:
            raise SystemExit(f"slopelander demo: error: {exc}") from None
    elif args.arducopter is not None:
        raise SystemExit("slopelander demo: error: --arducopter is for --autopilot ardupilot")
    result = run_demo(
        out=args.out,
        slope_deg=args.slope,
        speed=args.time_scale,
        table=args.table,
        plot=not args.no_plot,
        autopilot=args.autopilot,
        arducopter=args.arducopter,
    )
    print(result.summary())
    return 0 if result.outcome == "LANDED_AND_RESET" else 3
