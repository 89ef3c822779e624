"""The options ``map`` and ``table`` share (the grid, the model, reverse thrust's end, a Dask
cluster) and what they do with them before the sweep.

Outside the envelope package, whose ``__init__`` imports scipy and matplotlib: the arguments are
parsed, and the outputs checked, before any of that is imported.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

#: exit code after Ctrl-C (128 + SIGINT), as a shell reports it
INTERRUPTED = 130


def add_sweep_options(p: argparse.ArgumentParser) -> None:
    """The grid, model, reverse-thrust and cluster options of a sweep."""
    g = p.add_argument_group("grid")
    g.add_argument("--slope-step", type=float, default=1.0, help="deg (default 1)")
    g.add_argument("--speed-step", type=float, default=0.1, help="m/s (default 0.1)")
    g.add_argument("--slope-min", type=float, default=0.0, help="deg")
    g.add_argument("--slope-max", type=float, default=60.0, help="deg")
    g.add_argument("--speed-min", type=float, default=0.5, help="m/s")
    g.add_argument("--speed-max", type=float, default=3.0, help="m/s")
    p.add_argument("--params", metavar="FILE", help="model parameter YAML (default: shipped set)")
    p.add_argument(
        "--refine", action="store_true", help="continuous torque optimisation after the 16 level pairs"
    )
    p.add_argument(
        "--optimal-angle",
        action="store_true",
        help="search the uphill leg angle instead of the paper's linear rule",
    )
    g = p.add_argument_group("reverse thrust (strategies with reverse thrust)")
    g.add_argument(
        "--reverse-duration",
        type=float,
        metavar="S",
        help="end the reverse thrust this long after its command (default: held to the model's "
        "horizon); the companion holds it at least reflex.reverse_thrust_ms, then until still",
    )
    g.add_argument(
        "--reverse-ramp",
        type=float,
        default=0.0,
        metavar="S",
        help="then ramp it to zero over this long (default 0: a step; the script's reflex.reverse_ramp_ms)",
    )
    p.add_argument(
        "--dask",
        metavar="ADDRESS",
        help="run the landings on a Dask cluster, e.g. tcp://host:8786 (docs/cluster.md)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def thrust_end(args: argparse.Namespace) -> dict:
    """The strategy options for ``--reverse-duration``/``--reverse-ramp``, checked before any work."""
    from slopelander.envelope.presets import StrategyError
    from slopelander.model.conditions import ConditionError, LandingConditions

    if args.reverse_duration is None:
        if args.reverse_ramp:
            raise StrategyError("--reverse-ramp needs --reverse-duration (a held thrust never ramps)")
        return {}
    try:
        LandingConditions(
            reverse_percent=100.0, reverse_duration=args.reverse_duration, reverse_ramp=args.reverse_ramp
        ).validate()
    except ConditionError as e:
        raise StrategyError(f"--reverse-duration / --reverse-ramp: {e}") from None
    return {"reverse_duration": args.reverse_duration, "reverse_ramp": args.reverse_ramp}


def setup(args: argparse.Namespace):
    """The sweep's axes, model, Dask client (or None) and progress setting."""
    from slopelander.envelope.axes import MapAxes
    from slopelander.model import Model

    axes = MapAxes.build(
        args.slope_step,
        args.speed_step,
        slope_min=args.slope_min,
        slope_max=args.slope_max,
        speed_min=args.speed_min,
        speed_max=args.speed_max,
    )
    model = Model.from_file(args.params) if args.params else Model.default()
    client = None
    if args.dask:
        from slopelander.envelope.cluster import connect

        client = connect(args.dask)
    progress = None if not args.quiet else False
    return axes, model, client, progress


def interrupted(command: str, written: list[Path]) -> int:
    """Ctrl-C: one line on what is on disk, no traceback, exit code 130."""
    if written:
        names = ", ".join(str(p) for p in written)
        print(f"slopelander {command}: interrupted; partial results written: {names}", file=sys.stderr)
    else:
        print(f"slopelander {command}: interrupted; nothing written", file=sys.stderr)
    return INTERRUPTED
