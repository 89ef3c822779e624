"""``slopelander table``: the preset lookup table the controller flies with (YAML)."""

from __future__ import annotations

import argparse
import shlex
import sys
import time

from slopelander.commands.envelope_options import add_sweep_options, interrupted, setup, thrust_end
from slopelander.outputs import check_output


def register(subparsers: argparse._SubParsersAction) -> None:
    t = subparsers.add_parser(
        "table",
        help="write the preset lookup table the controller flies with",
        description="Choose presets per (slope, speed) and write the YAML table. Exit codes: 0 "
        "written, 1 an error, 2 a usage error, 130 interrupted (nothing written).",
    )
    t.add_argument("--out", required=True, metavar="FILE", help="table file (.yaml); its folder must exist")
    t.add_argument(
        "--strategy",
        default="rvt",
        choices=("asymmetric", "angle", "rvt"),
        help="how the vehicle lands (default rvt: linear uphill angle + 100 %% reverse thrust)",
    )
    add_sweep_options(t)
    t.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_output(args.out, "--out")
    from slopelander.envelope.presets import STRATEGIES
    from slopelander.envelope.table import build_table, write_table

    ends = thrust_end(args)
    axes, model, client, progress = setup(args)
    strategy = STRATEGIES[args.strategy].with_options(
        refine=args.refine, optimal_angle=args.optimal_angle, **ends
    )
    command = "slopelander " + shlex.join(sys.argv[1:]) if sys.argv[1:] else None
    t0 = time.perf_counter()
    try:
        doc, presets = build_table(model, axes, strategy, client=client, progress=progress, command=command)
    except KeyboardInterrupt:
        return interrupted("table", [])  # the table is written only once it is complete
    finally:
        if client is not None:
            client.close()
    path = write_table(doc, args.out)
    landed = presets.landed()
    print(
        f"wrote {path}: {axes.shape[0]} slopes x {axes.shape[1]} speeds, "
        f"{int(landed.sum())} cells land, {time.perf_counter() - t0:.1f} s"
    )
    return 0
