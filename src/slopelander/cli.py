"""The ``slopelander`` command: one entry point over the commands of
:mod:`slopelander.commands` (one module each, with ``register(subparsers)``; the handler it
installs calls a function a user could call from Python).

Only the named command's module is imported, so a command answers at once
(benchmarks/cli_latency.py measures it).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys

from slopelander import __version__
from slopelander.commands import COMMANDS
from slopelander.commands.options import CommandParser
from slopelander.errors import SlopelanderError

SIM_EXTRA = ("numba", "scipy", "matplotlib", "tqdm", "cma", "lupa", "c3d")
"""The importable names the ``sim`` extra installs (pyproject.toml)."""

#: the entry-point group through which another installed part adds a command: the simulator's
#: ``demo`` lives with the simulator (pyproject.toml), so the core never imports it
COMMANDS_GROUP = "slopelander.commands"

#: the modules that add subcommands (:data:`slopelander.commands.COMMANDS`)
SUBCOMMAND_MODULES = COMMANDS


def subcommand_modules() -> dict[str, tuple[tuple[str, ...], bool]]:
    """Every module that adds subcommands: the installed :data:`COMMANDS_GROUP` entry points
    (each needs the ``sim`` extra) then :data:`SUBCOMMAND_MODULES`."""
    from importlib.metadata import entry_points

    found = {ep.value: ((ep.name,), True) for ep in entry_points(group=COMMANDS_GROUP)}
    return {**found, **SUBCOMMAND_MODULES}


def missing_sim_module() -> str | None:
    """The first module of the ``sim`` extra that is not installed (found without importing it)."""
    return next((m for m in SIM_EXTRA if importlib.util.find_spec(m) is None), None)


def named_command(argv: list[str]) -> str | None:
    """The subcommand ``argv`` starts with, or None (no command, a top-level option such as
    ``--help``, or a name that is not a command: the whole parser answers those)."""
    if not argv or argv[0].startswith("-"):
        return None
    return argv[0] if any(argv[0] in names for names, _ in subcommand_modules().values()) else None


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser; with ``only``, that subcommand's alone: the modules of the
    others (the leg driver, yaml, pyserial) are not imported, so a command starts sooner."""
    parser = argparse.ArgumentParser(
        prog="slopelander",
        description="Fast multirotor landing on steep slopes.",
    )
    parser.add_argument("--version", action="version", version=f"slopelander {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=CommandParser)
    missing = missing_sim_module()
    for module, (names, needs_sim) in subcommand_modules().items():
        if only is not None and only not in names:
            continue
        if needs_sim and missing:
            _needs_extra(subparsers, names, missing)
            continue
        try:
            importlib.import_module(module).register(subparsers)
        except ModuleNotFoundError as exc:
            _needs_extra(subparsers, names, exc.name or str(exc))
    return parser


def _needs_extra(subparsers: argparse._SubParsersAction, names: tuple[str, ...], missing: str) -> None:
    """Subcommands whose dependencies are not installed: listed, and each says what to install."""

    def refuse(args: argparse.Namespace) -> int:
        raise SlopelanderError(
            f"needs the simulation extra ({missing} is not installed): pip install 'slopelander[sim]'"
        )

    for name in names:
        p = subparsers.choices.get(name) or subparsers.add_parser(
            name, help="(needs: pip install 'slopelander[sim]')", add_help=False
        )
        p.set_defaults(handler=refuse)


def main(argv: list[str] | None = None) -> int:
    """Run one command. Without ``argv`` it is this process's own command line (the
    ``slopelander`` script, ``python -m slopelander.cli``): then a command that asks for it
    (``simulate``) ends the process as soon as it has finished and its output is flushed, without
    the interpreter's teardown of numba, LLVM and numpy (0.3-0.4 s of CPU, a quarter of a second
    ``simulate``)."""
    own = argv is None
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(named_command(argv))
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help()
        return 2
    try:
        rc = int(args.handler(args) or 0)
    except SlopelanderError as exc:
        print(f"slopelander {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as exc:
        if (exc.name or "").split(".")[0] not in SIM_EXTRA:
            raise
        print(
            f"slopelander {args.command}: error: needs the simulation extra ({exc.name} is not "
            "installed): pip install 'slopelander[sim]'",
            file=sys.stderr,
        )
        return 1
    except KeyboardInterrupt:
        # Commands that write files as they go (map) say what they wrote themselves.
        print(f"slopelander {args.command}: interrupted", file=sys.stderr)
        return 130
    if own and getattr(args, "exit_without_teardown", False):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(rc)  # every file it wrote is closed; nothing is left to clean up
    return rc


if __name__ == "__main__":
    sys.exit(main())
