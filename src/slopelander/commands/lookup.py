"""``slopelander lookup``: from the lookup table to the legs' preset, without writing Python."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "lookup",
        help="print the legs' preset the lookup table gives for a slope and an impact speed",
        description="Print the friction torques and leg angles the lookup table gives for a landing "
        "at SLOPE deg and a vertical impact speed of SPEED m/s, with the outcome the model predicts. "
        "A request outside the table is refused, never extrapolated. "
        "Exit codes: 0 done, 1 an error, 2 a usage error, 130 interrupted.",
    )
    p.add_argument("--slope", type=float, required=True, help="landing slope, deg")
    p.add_argument("--speed", type=float, required=True, help="vertical impact speed, m/s")
    p.add_argument("--table", type=Path, default=None, help="lookup table (default: the shipped one)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable

    path = args.table or DEFAULT_TABLE
    p = LookupTable.load(path).lookup(args.slope, args.speed)
    print(f"table: {path}")
    print(f"landing at {args.slope:g} deg, {args.speed:g} m/s:")
    print(f"  friction torque uphill {p.tau_up:.2f} N*m, downhill {p.tau_down:.2f} N*m (per joint)")
    print(f"  leg angle uphill {p.angle_up_deg:.1f} deg, downhill {p.angle_down_deg:.1f} deg")
    print(f"  model predicts: {p.outcome}, margin {p.margin:.2f} (cell {p.cell})")
    return 0
