"""``slopelander synth``: a dataset of synthetic drops from a 'truth' model."""

from __future__ import annotations

import argparse
from pathlib import Path

from slopelander.commands.ident_options import IdentCliError, add_model_options, build_model
from slopelander.commands.options import renamed
from slopelander.outputs import check_output_dir


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "synth",
        help="write a dataset of synthetic drops from a 'truth' model",
        description="Simulate drops over the paper's spread (0-45 deg, 1-3 m/s, the paper's torque "
        "levels) with a truth model and write them as recordings with motion-capture noise. "
        "Exit codes: 0 done, 1 an error, 2 a usage error, 130 interrupted.",
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="dataset folder to write")
    p.add_argument("--drops", type=int, default=10, help="number of drops")
    p.add_argument("--seed", type=int, default=0, help="seed of the drop conditions and the noise")
    p.add_argument("--duration", type=float, default=1.0, help="seconds recorded after first contact")
    p.add_argument("--position-noise", type=float, default=1e-3, help="m (standard deviation)")
    p.add_argument("--angle-noise", type=float, default=0.3, help="deg (standard deviation)")
    p.add_argument("--latency", type=float, default=0.002, help="s (default 2 ms, as NoiseModel)")
    p.add_argument("--rate", type=float, default=200.0, help="sample rate, Hz")
    p.add_argument("--slope-min", type=float, default=0.0, help="deg, within 0..45")
    p.add_argument("--slope-max", type=float, default=45.0, help="deg, within 0..45")
    p.add_argument("--speed-min", type=float, default=1.0, help="m/s, within 1..3")
    p.add_argument("--speed-max", type=float, default=3.0, help="m/s, within 1..3")
    p.add_argument("--no-flips", action="store_true", help="leave out the drops the truth flips on")
    add_model_options(p, "truth")
    renamed(p, "--slopes", "--slope-min", "--slope-max")
    renamed(p, "--speeds", "--speed-min", "--speed-max")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_output_dir(args.out, "--out")
    from slopelander.ident.recording import write_dataset
    from slopelander.ident.synth import NoiseModel, paper_drops, survived, synthesize

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
    try:
        conds = paper_drops(
            args.drops,
            args.seed,
            slopes=(args.slope_min, args.slope_max),
            speeds=(args.speed_min, args.speed_max),
        )
    except ValueError as exc:
        raise IdentCliError(f"--slope-min/max, --speed-min/max: {exc}") from None
    model = build_model(args)
    if args.no_flips:
        kept = survived(model, conds)
        if not kept:
            raise IdentCliError(
                "--no-flips: the truth flips on every drop; choose gentler slopes or speeds "
                "(--slope-max, --speed-max)"
            )
        if len(kept) < len(conds):
            print(f"left out {len(conds) - len(kept)} of {len(conds)} drops: the truth flips on them")
        conds = kept
    source = "synthetic: " + (" ".join(f"without {e}" for e in args.without) or "full model")
    drops = synthesize(
        model,
        conds,
        noise,
        seed=args.seed,
        duration=args.duration,
        source=source,
    )
    write_dataset(drops, args.out)
    flips = sum(d.outcome is not None and d.outcome.name == "FLIP" for d in drops)
    print(f"wrote {len(drops)} drops ({flips} flipped) to {args.out}")
    return 0
