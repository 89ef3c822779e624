"""The ``slopelander`` command: one entry point, one thin subcommand per part.

Each part owns a ``cli`` module with ``register(subparsers)``; the handler it
installs calls a function a user could call from Python.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from slopelander import __version__
from slopelander.errors import SlopelanderError

# Modules that add subcommands, in the order they appear in ``--help``.
SUBCOMMAND_MODULES = [
    "slopelander.demo_cli",
    "slopelander.simulate_cli",
    "slopelander.legs.cli",
    "slopelander.envelope.cli",
    "slopelander.land_cli",
]


class _Parser(argparse.ArgumentParser):
    """Every subcommand's ``--help`` shows the defaults."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", argparse.ArgumentDefaultsHelpFormatter)
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="slopelander",
        description="Fast multirotor landing on steep slopes.",
    )
    parser.add_argument("--version", action="version", version=f"slopelander {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help()
        return 2
    try:
        return int(args.handler(args) or 0)
    except SlopelanderError as exc:
        print(f"slopelander {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
