"""``slopelander map KIND`` and ``slopelander table``: thin layers over envelope.reports/table.

Outside the envelope package, whose ``__init__`` imports scipy and matplotlib: the arguments are
parsed, and the outputs checked, before any of that is imported.
"""

from __future__ import annotations

import argparse
import json
import math
import numbers
import shlex
import sys
import time
from pathlib import Path

from slopelander.outputs import check_output, check_output_dir, files_changed_since

INTERRUPTED = 130
MAP_KINDS = ("symmetric", "asymmetric", "angle", "rvt", "rigid", "uncertainty", "robustness")
"""The maps ``envelope.reports.make_map`` draws (a test keeps the two lists equal)."""
"""Exit code after Ctrl-C (128 + SIGINT), as a shell reports it."""


def _common(p: argparse.ArgumentParser) -> None:
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


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "map",
        help="landing maps of the paper's Sec. V (PNG + NPZ + CSV)",
        description="Compute a landing map over slope x vertical impact speed.",
    )
    p.add_argument("kind", choices=MAP_KINDS)
    p.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help="folder for the files (created if missing; its parent folder must exist)",
    )
    p.add_argument(
        "--config",
        default="rvt",
        choices=("symmetric", "asymmetric", "angle", "rvt", "rigid", "rigid_rvt"),
        help="presets flown by the uncertainty and robustness maps (default rvt)",
    )
    p.add_argument("--sets", type=int, default=3, help="parameter sets for 'uncertainty' (default 3)")
    p.add_argument("--draws", type=int, default=10, help="robustness draws per cell (default 10)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the parameter sets and draws")
    _common(p)
    p.set_defaults(handler=run_map)

    t = subparsers.add_parser(
        "table",
        help="write the preset lookup table the controller flies with",
        description="Choose presets per (slope, speed) and write the YAML table.",
    )
    t.add_argument("--out", required=True, metavar="FILE", help="table file (.yaml); its folder must exist")
    t.add_argument(
        "--strategy",
        default="rvt",
        choices=("asymmetric", "angle", "rvt"),
        help="how the vehicle lands (default rvt: linear uphill angle + 100 %% reverse thrust)",
    )
    _common(t)
    t.set_defaults(handler=run_table)


def thrust_end(args) -> dict:
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


def _setup(args):
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


def _interrupted(command: str, written: list[Path]) -> int:
    """Ctrl-C: one line on what is on disk, no traceback, exit code 130."""
    if written:
        names = ", ".join(str(p) for p in written)
        print(f"slopelander {command}: interrupted; partial results written: {names}", file=sys.stderr)
    else:
        print(f"slopelander {command}: interrupted; nothing written", file=sys.stderr)
    return INTERRUPTED


def run_map(args) -> int:
    check_output_dir(args.out, "--out")
    from slopelander.envelope.reports import make_map

    ends = thrust_end(args)
    axes, model, client, progress = _setup(args)
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
            config=args.config,
            sets=args.sets,
            seed=args.seed,
            draws=args.draws,
            client=client,
            progress=progress,
        )
    except KeyboardInterrupt:
        return _interrupted("map", files_changed_since(Path(args.out), started))
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


def run_table(args) -> int:
    check_output(args.out, "--out")
    from slopelander.envelope.presets import STRATEGIES
    from slopelander.envelope.table import build_table, write_table

    ends = thrust_end(args)
    axes, model, client, progress = _setup(args)
    strategy = STRATEGIES[args.strategy].with_options(
        refine=args.refine, optimal_angle=args.optimal_angle, **ends
    )
    command = "slopelander " + shlex.join(sys.argv[1:]) if sys.argv[1:] else None
    t0 = time.perf_counter()
    try:
        doc, presets = build_table(model, axes, strategy, client=client, progress=progress, command=command)
    except KeyboardInterrupt:
        return _interrupted("table", [])  # the table is written only once it is complete
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
