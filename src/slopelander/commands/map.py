"""``slopelander map KIND``: a landing map over slope x vertical impact speed (PNG, NPZ, CSV)."""

from __future__ import annotations

import argparse
import json
import math
import numbers
import time
from pathlib import Path

from slopelander.commands.envelope_options import add_sweep_options, interrupted, setup, thrust_end
from slopelander.commands.options import renamed
from slopelander.outputs import check_output_dir, files_changed_since

MAP_KINDS = ("symmetric", "asymmetric", "angle", "rvt", "rigid", "uncertainty", "robustness")
"""The maps ``envelope.reports.make_map`` draws (a test keeps the two lists equal)."""
STRATEGIES = ("symmetric", "asymmetric", "angle", "rvt", "rigid", "rigid_rvt")
"""The presets the uncertainty and robustness maps may fly."""


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "map",
        help="landing maps of the paper's Sec. V (PNG + NPZ + CSV)",
        description="Compute a landing map over slope x vertical impact speed and write it into "
        "--out. Exit codes: 0 written, 1 an error, 2 a usage error, 130 interrupted (it says "
        "which files it had written).",
    )
    p.add_argument("kind", choices=MAP_KINDS)
    p.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help="folder for the files (created if missing; its parent folder must exist)",
    )
    p.add_argument(
        "--strategy",
        default="rvt",
        choices=STRATEGIES,
        help="the presets flown by the uncertainty and robustness maps (default rvt)",
    )
    p.add_argument("--sets", type=int, default=3, help="parameter sets for 'uncertainty' (default 3)")
    p.add_argument("--draws", type=int, default=10, help="robustness draws per cell (default 10)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the parameter sets and draws")
    add_sweep_options(p)
    renamed(p, "--config", "--strategy")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_output_dir(args.out, "--out")
    from slopelander.envelope.reports import make_map

    ends = thrust_end(args)
    axes, model, client, progress = setup(args)
    t0 = time.perf_counter()
    started = time.time() - 1.0  # file times may be rounded to the second
    try:
        result = make_map(
            args.kind,
            args.out,
            model=model,
            axes=axes,
            refine=args.refine,
            optimal_angle=args.optimal_angle,
            thrust_end=ends,
            config=args.strategy,
            sets=args.sets,
            seed=args.seed,
            draws=args.draws,
            client=client,
            progress=progress,
        )
    except KeyboardInterrupt:
        return interrupted("map", files_changed_since(Path(args.out), started))
    finally:
        if client is not None:
            client.close()
    result["seconds"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(rounded(result), indent=2, default=float))
    return 0


def rounded(value: object, digits: int = 6) -> object:
    """Numbers as a person reads them: ``digits`` significant digits, so a sum of grid steps
    prints 57.9, not 57.900000000000006 (the summary file keeps the full values)."""
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [rounded(v, digits) for v in value]
    if isinstance(value, numbers.Real) and not isinstance(value, (bool, numbers.Integral)):
        v = float(value)
        return float(f"{v:.{digits}g}") if math.isfinite(v) else v
    return value
