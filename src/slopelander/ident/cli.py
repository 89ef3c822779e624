"""``slopelander synth|compare|fit|diagnose``: thin layers over the ident modules."""

from __future__ import annotations

import argparse
from pathlib import Path

from slopelander.errors import SlopelanderError
from slopelander.model import Model, ParameterError, load_effects


class IdentCliError(SlopelanderError):
    """A command-line setting of the identification commands that cannot be used."""


def _model_args(p: argparse.ArgumentParser, what: str) -> None:
    g = p.add_argument_group(f"{what} model")
    g.add_argument("--params", type=Path, metavar="FILE", help="model parameter YAML (default: shipped set)")
    g.add_argument("--without", nargs="+", default=[], metavar="EFFECT", help="switch built-in effects off")
    g.add_argument("--effects-file", type=Path, metavar="FILE", help="Python file with user effects to add")
    g.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE", help="override parameters")


def build_model(args: argparse.Namespace) -> Model:
    """The model the options describe: a parameter file, effects off, user effects, overrides."""
    model = Model.from_file(str(args.params)) if args.params else Model.default()
    if args.without:
        model = model.without(*args.without)
    if args.effects_file:
        for effect in load_effects(args.effects_file):
            model = model.with_user_effect(effect)
    values = {}
    for item in args.set:
        name, _, text = item.partition("=")
        try:
            values[name] = float(text)
        except ValueError:
            raise IdentCliError(f"--set {item!r}: expected NAME=NUMBER") from None
    if values:
        try:
            model = model.with_params(**values)
        except ParameterError as exc:
            raise IdentCliError(f"--set: {exc}") from None
    return model


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "synth", help="write a dataset of synthetic drops from a 'truth' model",
        description="Simulate drops over the paper's spread (0-45 deg, 1-3 m/s, the paper's torque "
                    "levels) with a truth model and write them as recordings with motion-capture noise.")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="dataset folder to write")
    p.add_argument("--drops", type=int, default=10, help="number of drops")
    p.add_argument("--seed", type=int, default=0, help="seed of the drop conditions and the noise")
    p.add_argument("--duration", type=float, default=1.0, help="seconds recorded after first contact")
    p.add_argument("--position-noise", type=float, default=1e-3, help="m (standard deviation)")
    p.add_argument("--angle-noise", type=float, default=0.3, help="deg (standard deviation)")
    p.add_argument("--latency", type=float, default=0.005, help="s")
    p.add_argument("--rate", type=float, default=200.0, help="sample rate, Hz")
    _model_args(p, "truth")
    p.set_defaults(handler=run_synth)
    register_compare(subparsers)


def run_synth(args: argparse.Namespace) -> int:
    from slopelander.ident.recording import write_dataset
    from slopelander.ident.synth import NoiseModel, paper_drops, synthesize

    if args.out.exists() and any(args.out.glob("*.csv")):
        raise IdentCliError(f"--out {args.out} already holds drops; choose an empty folder")
    if not 1 <= args.drops <= 1000:
        raise IdentCliError("--drops must lie within 1..1000")
    if not 0.05 <= args.duration <= 10:
        raise IdentCliError("--duration must lie within 0.05..10 s")
    try:
        noise = NoiseModel(args.position_noise, args.angle_noise, args.latency, args.rate)
    except ValueError as exc:
        raise IdentCliError(str(exc)) from None
    model = build_model(args)
    source = "synthetic: " + (" ".join(f"without {e}" for e in args.without) or "full model")
    drops = synthesize(model, paper_drops(args.drops, args.seed), noise, seed=args.seed,
                       duration=args.duration, source=source)
    write_dataset(drops, args.out)
    flips = sum(d.outcome is not None and d.outcome.name == "FLIP" for d in drops)
    print(f"wrote {len(drops)} drops ({flips} flipped) to {args.out}")
    return 0


def _dataset_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("dataset", type=Path, metavar="DATASET",
                   help="folder of drop recordings (docs/recordings.md)")


def register_compare(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "compare", help="compare the model with recorded drops: NRMSE, phases, outcomes, report",
        description="Simulate every recorded drop, report NRMSE per state, drop and phase, outcome "
                    "matches and where the residual concentrates; write a Markdown report with a plot "
                    "per drop.")
    _dataset_arg(p)
    p.add_argument("--report", type=Path, metavar="DIR", help="folder for report.md and one PNG per drop")
    _model_args(p, "analysed")
    p.set_defaults(handler=run_compare)


def run_compare(args: argparse.Namespace) -> int:
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
    print("  per phase: " + ", ".join(f"{p} {v:.4f} ({100 * share[p]:.0f} % of residual)"
                                      for p, v in c.per_phase().items()))
    for w in c.worst_windows(3):
        print(f"  worst: {w.drop} {w.start:.2f}-{w.end:.2f} s ({w.phase}, {w.state}): {100 * w.share:.1f} %")
    if args.report:
        out = write_report(c, args.report, model_note=f"Model: effects {', '.join(model.effects)}.")
        print(f"report: {out}")
    return 0
