"""``slopelander compare``: the model against recorded drops, or against the landings of a flight log."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from slopelander.commands.ident_options import IdentCliError, add_model_options, build_model, count, plain
from slopelander.outputs import check_output, check_output_dir


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "compare",
        help="compare the model with recorded drops, or with the landings of a flight log",
        description="Simulate every recorded drop, report NRMSE per state, drop and phase, outcome "
        "matches and where the residual concentrates; write a Markdown report with a plot "
        "per drop. Given a flight log instead (an ArduPilot DataFlash log or a MAVLink tlog, told by "
        "its content), compare each of its landings with the model at that landing's conditions on "
        "what the log can see, and write a JSON and a plot per landing (docs/flight-logs.md).",
    )
    p.add_argument(
        "dataset",
        type=Path,
        metavar="DATASET|LOG",
        help="folder of drop recordings (docs/recordings.md), or a flight log file",
    )
    p.add_argument(
        "--report",
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
    g = p.add_argument_group("flight log (docs/flight-logs.md)")
    g.add_argument("--landing", type=count(1), metavar="N", help="only the log's N-th landing")
    g.add_argument("--slope", type=float, metavar="DEG", help="the roof's slope, instead of the log's")
    g.add_argument(
        "--tau", type=float, nargs=2, metavar=("UP", "DOWN"), help="legs' friction torques, N*m per joint"
    )
    g.add_argument(
        "--angles", type=float, nargs=2, metavar=("UP", "DOWN"), help="leg angles, deg (not in the logs)"
    )
    add_model_options(p, "analysed")
    p.set_defaults(handler=run)


_LOG_OPTIONS = ("landing", "slope", "tau", "angles")


def run(args: argparse.Namespace) -> int:
    path = args.dataset
    if path.is_file() or (not path.exists() and path.suffix.lower() in (".bin", ".tlog")):
        return run_log(args)  # a file is read as a log whatever its name; a missing log says so
    given = [f"--{n}" for n in _LOG_OPTIONS if getattr(args, n) is not None]
    if given:
        raise IdentCliError(
            f"{', '.join(given)}: only for a flight log, and {args.dataset} is a dataset folder"
        )
    check_output_dir(args.report, "--report")
    check_output(args.json, "--json")
    from slopelander.ident.compare import compare
    from slopelander.ident.recording import STATES, load_dataset
    from slopelander.ident.report import write_report

    drops = load_dataset(args.dataset)
    model = build_model(args)
    c = compare(model, drops)
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
    if args.report:
        out = write_report(c, args.report, model_note=f"Model: effects {', '.join(model.effects)}.")
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
        }  # fmt: skip
        args.json.write_text(json.dumps(figures, indent=1, default=plain) + "\n")
        print(f"json: {args.json}")
    return 0


def run_log(args: argparse.Namespace) -> int:
    """``compare LOG``: each landing of a flight log against the model (docs/flight-logs.md)."""
    from slopelander.ident.flightlog.compare import compare_log, write_results
    from slopelander.ident.flightlog.conditions import Given

    report = args.report if args.report is not None else Path(f"{args.dataset.stem}-compare")
    check_output_dir(report, "--report")
    check_output(args.json, "--json")
    for name in ("tau", "angles"):
        values = getattr(args, name)
        if values is not None and not all(map(math.isfinite, values)):
            raise IdentCliError(f"--{name} {' '.join(map(str, values))}: not numbers")
    if args.slope is not None and not math.isfinite(args.slope):
        raise IdentCliError(f"--slope {args.slope}: not a number")
    model = build_model(args)
    given = Given(
        args.slope,
        tuple(args.tau) if args.tau is not None else None,
        tuple(args.angles) if args.angles is not None else None,
    )
    results = compare_log(model, args.dataset, given, args.landing)
    for r in results:
        print("\n".join(r.lines()))
    written = write_results(results, report, args.json)
    print("report: " + ", ".join(str(p) for p in written))
    return 0
