"""``slopelander import``: raw motion-capture takes (C3D, Vicon/Motive CSV, Qualisys TSV) as a
dataset of drops (docs/import.md)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "import",
        help="turn raw motion-capture takes (C3D, Vicon/Motive CSV, Qualisys TSV) into a dataset",
        description="Read each take, fit the body's marker cluster, find the roof's plane and fall line, "
        "first contact and the impact state, compute the rates (Savitzky-Golay) and the noise, and "
        "write one drop per take (docs/import.md). Nothing is written unless every take imports. "
        "Exit codes: 0 done, 1 an error, 2 a usage error, 130 interrupted.",
    )
    p.add_argument("takes", type=Path, nargs="+", metavar="TAKE", help="take files, or folders of them")
    p.add_argument(
        "--markers", type=Path, required=True, metavar="YAML", help="the markers file (docs/import.md)"
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="dataset folder to create")
    p.add_argument(
        "--keep-nonplanar",
        action="store_true",
        help="put takes that are not planar enough into the dataset too (default: DIR/not-planar/)",
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from slopelander.ident.mocap.importer import import_takes

    done = import_takes(args.takes, args.markers, args.out, keep_nonplanar=args.keep_nonplanar)
    for d in done:
        print(d.lines[0])
        print(d.lines[1])
    flagged = [d.drop.name for d in done if not d.planar]
    kept = len(done) if args.keep_nonplanar else len(done) - len(flagged)
    line = f"wrote {kept} drops to {args.out}"
    if flagged:
        where = "kept in the dataset" if args.keep_nonplanar else f"in {args.out / 'not-planar'}"
        line += f"; not planar enough ({where}): {', '.join(flagged)}"
    print(line)
    return 0
