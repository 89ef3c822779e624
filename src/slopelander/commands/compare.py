"""``slopelander compare``: the model against recorded drops, or against the landings of a flight log."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from slopelander.commands.ident_options import (
    IdentCliError,
    add_align_option,
    add_model_options,
    align_s,
    build_model,
    count,
    plain,
)
from slopelander.commands.options import renamed
from slopelander.outputs import check_output, check_output_dir


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "compare",
        help="compare the model with recorded drops, or with the landings of a flight log",
        description="Simulate every recorded drop, report NRMSE per state, drop and phase, outcome "
        "matches and where the residual concentrates; write a Markdown report with a plot "
        "per drop. Given a flight log instead (an ArduPilot DataFlash log or a MAVLink tlog, told by "
        "its content), compare each of its landings with the model at that landing's conditions on "
        "what the log can see, and write a JSON and a plot per landing (docs/flight-logs.md). "
        "Exit codes: 0 done, 1 an error, 2 a usage error, 130 interrupted.",
    )
    p.add_argument(
        "dataset",
        type=Path,
        metavar="DATASET|LOG",
        help="folder of drop recordings (docs/recordings.md), or a flight log file",
    )
    p.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="folder for report.md and one PNG per drop; for a log, its JSON and PNG per landing "
        "(default for a log: <log name>-compare in the current folder)",
    )
    p.add_argument(
        "--json",
        type=Path,
        metavar="FILE",
        help="also write the figures as JSON (for a log: every landing's)",
    )
    add_align_option(p)
    g = p.add_argument_group("flight log (docs/flight-logs.md)")
    g.add_argument("--landing", type=count(1), metavar="N", help="only the log's N-th landing")
    g.add_argument("--slope", type=float, metavar="DEG", help="the roof's slope, instead of the log's")
    g.add_argument("--tau-up", type=float, metavar="NM", help="uphill legs' friction torque, N*m per joint")
    g.add_argument("--tau-down", type=float, metavar="NM", help="downhill legs' (with --tau-up)")
    g.add_argument("--angle-up", type=float, metavar="DEG", help="uphill leg angle, deg (not in the logs)")
    g.add_argument("--angle-down", type=float, metavar="DEG", help="downhill leg angle (with --angle-up)")
    add_model_options(p, "analysed")
    renamed(p, "--report", "--out")
    renamed(p, "--tau", "--tau-up", "--tau-down")
    renamed(p, "--angles", "--angle-up", "--angle-down")
    p.set_defaults(handler=run)


_LOG_OPTIONS = ("landing", "slope", "tau_up", "tau_down", "angle_up", "angle_down")


def run(args: argparse.Namespace) -> int:
    path = args.dataset
    if path.is_file() or (not path.exists() and path.suffix.lower() in (".bin", ".tlog")):
        return run_log(args)  # a file is read as a log whatever its name; a missing log says so
    given = [f"--{n.replace('_', '-')}" for n in _LOG_OPTIONS if getattr(args, n) is not None]
    if given:
        raise IdentCliError(
            f"{', '.join(given)}: only for a flight log, and {args.dataset} is a dataset folder"
        )
    check_output_dir(args.out, "--out")
    check_output(args.json, "--json")
    from slopelander.ident.clocks import align_windows
    from slopelander.ident.compare import compare
    from slopelander.ident.recording import STATES, load_dataset
    from slopelander.ident.report import write_report

    window = align_s(args)
    drops = load_dataset(args.dataset)
    model = build_model(args)
    windows = align_windows(drops, window)
    c = compare(model, drops, align=windows)
    ok, known = c.outcome_matches()
    print(f"NRMSE {c.nrmse:.4f} over {len(drops)} drops (angular states x2); outcomes match {ok}/{known}")
    print("  per state: " + ", ".join(f"{s} {v:.4f}" for s, v in zip(STATES, c.per_state, strict=True)))
    share = c.phase_share()
    print(
        "  per phase: "
        + ", ".join(f"{p} {v:.4f} ({100 * share[p]:.0f} % of residual)" for p, v in c.per_phase().items())
    )
    for w in c.worst_windows(3):
        print(f"  worst: {w.drop} {w.start:.2f}-{w.end:.2f} s ({w.phase}, {w.state}): {100 * w.share:.1f} %")
    if args.out:
        out = write_report(c, args.out, model_note=f"Model: effects {', '.join(model.effects)}.")
        print(f"report: {out}")
    if args.json:
        figures = {
            "nrmse": c.nrmse,
            "drops": [d.name for d in drops],
            "outcomes_match": ok,
            "outcomes_known": known,
            "per_state": dict(zip(STATES, map(float, c.per_state), strict=True)),
            "per_phase": {p: float(v) for p, v in c.per_phase().items()},
            "phase_share": {p: float(v) for p, v in share.items()},
            "worst": [
                {"drop": w.drop, "start_s": w.start, "end_s": w.end, "phase": w.phase, "state": w.state,
                 "share": w.share}
                for w in c.worst_windows(3)
            ],
            "effects": list(model.effects),
            # each drop's clock as compared (docs/ident.md "Clocks"): window and lag, s
            "clocks": {
                d.name: {"window_s": w, "lag_s": dc.lag}
                for d, w, dc in zip(drops, windows, c.drops, strict=True)
            },
        }  # fmt: skip
        args.json.write_text(json.dumps(figures, indent=1, default=plain) + "\n")
        print(f"json: {args.json}")
    return 0


def run_log(args: argparse.Namespace) -> int:
    """``compare LOG``: each landing of a flight log against the model (docs/flight-logs.md)."""
    from slopelander.ident.flightlog.compare import compare_log, write_results
    from slopelander.ident.flightlog.conditions import Given

    report = args.out if args.out is not None else Path(f"{args.dataset.stem}-compare")
    check_output_dir(report, "--out")
    check_output(args.json, "--json")
    for name in ("slope", *_LOG_OPTIONS[2:]):
        value = getattr(args, name)
        if value is not None and not math.isfinite(value):
            raise IdentCliError(f"--{name.replace('_', '-')} {value}: not a number")
    model = build_model(args)
    given = Given(args.slope, _pair(args, "tau"), _pair(args, "angle"))
    results = compare_log(model, args.dataset, given, args.landing)
    for r in results:
        print("\n".join(r.lines()))
    written = write_results(results, report, args.json)
    print("report: " + ", ".join(str(p) for p in written))
    return 0


def _pair(args: argparse.Namespace, name: str) -> tuple[float, float] | None:
    """``--NAME-up`` and ``--NAME-down`` as one pair, or None when neither is given."""
    up, down = getattr(args, f"{name}_up"), getattr(args, f"{name}_down")
    if (up is None) != (down is None):
        raise IdentCliError(
            f"--{name}-up and --{name}-down go together: give both, or neither to read the log's"
        )
    return None if up is None else (up, down)
