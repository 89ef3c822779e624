"""``slopelander params``: the model's parameters, and a commented file to start an override from."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from slopelander.commands.options import renamed
from slopelander.errors import SlopelanderError
from slopelander.outputs import check_output


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "params",
        help="list the model parameters, or write them as a commented file to start an override from",
        description="List the model's parameters (value, unit, provenance). With --out, write the "
        "shipped parameter file with a comment per parameter (meaning, unit, allowed range); an "
        "override file passed with --params needs only the parameters it changes. Exit codes: 0 "
        "done, 1 an error, 2 a usage error.",
    )
    p.add_argument(
        "--out",
        nargs="?",
        const="-",
        metavar="FILE",
        help="write the commented parameter file to FILE (an existing file is not overwritten), "
        "or to standard output without FILE",
    )
    p.add_argument("--params", type=Path, metavar="FILE", help="start from this parameter file instead")
    renamed(p, "--dump", "--out")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if args.out not in (None, "-"):
        out = Path(args.out)
        check_output(out, "--out")
        if out.exists():
            raise SlopelanderError(f"--out {out} exists; remove it or choose another name")
    from slopelander.model import ModelParams
    from slopelander.model.parameters import SPECS, commented_yaml

    params = ModelParams.load(args.params) if args.params else ModelParams.default()
    if args.out is None:
        for spec in SPECS:
            v = params.values[spec.name]
            print(f"{spec.name:26s} {v.value:<10g} {spec.unit:11s} {v.provenance:10s} {spec.description}")
        print(f"effects: {', '.join(params.effects)}")
        return 0
    text = commented_yaml(params)
    if args.out == "-":
        sys.stdout.write(text)
    else:
        Path(args.out).write_text(text)
        print(f"wrote {args.out}: {len(SPECS)} parameters; keep only those you change, then --params FILE")
    return 0
