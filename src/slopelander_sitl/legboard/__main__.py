"""``python -m slopelander_sitl.legboard``: the leg board's firmware over a plant model, on a
pseudo-terminal."""

from __future__ import annotations

import argparse
import json
import signal
import sys

from slopelander_sitl.legboard.runtime import RUNTIMES, RuntimeChoiceError
from slopelander_sitl.legboard.server import CLOCKS, FAULT_KINDS, BoardServer, FaultSpec
from slopelander_sitl.parent_watch import watch_parent


def _json_object(parser: argparse.ArgumentParser, option: str, file, what: str) -> dict:
    """The JSON object in ``file`` (an open option file, or None: empty); a parser error otherwise."""
    if file is None:
        return {}
    try:
        obj = json.load(file)
    except ValueError as exc:
        parser.error(f"{option} {file.name}: not JSON: {exc}")
    if not isinstance(obj, dict):
        parser.error(f"{option} {file.name}: expected a JSON object of {what}")
    return obj


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m slopelander_sitl.legboard",
        description="Simulated leg board speaking the leg protocol on a pseudo-terminal.",
    )
    parser.add_argument("--link", help="symlink the pty's slave device here")
    parser.add_argument("--control", help="control socket path (default: LINK.ctl)")
    parser.add_argument("--speed", type=float, default=1.0, help="board seconds per wall second (default 1)")
    parser.add_argument(
        "--clock",
        choices=CLOCKS,
        default="wall",
        help="board time: wall = --speed x wall time (default); external = only the times a "
        "simulated vehicle sends over the control socket (op advance); it stands still without them",
    )
    parser.add_argument("--seed", type=int, default=0, help="noise seed")
    parser.add_argument(
        "--status-ms", type=int, default=100, help="status period in board ms when HELLO asks for 0"
    )
    parser.add_argument(
        "--no-angle-stop", action="store_true", help="behave like the paper's prototype: no SET_ANGLE"
    )
    parser.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="KIND[:ARG][@T]",
        help=f"inject a fault ({', '.join(FAULT_KINDS)}); @T = at board time T s",
    )
    parser.add_argument(
        "--runtime",
        choices=RUNTIMES,
        default="auto",
        help="where the firmware runs: auto = MicroPython if SLOPELANDER_MICROPYTHON names one, "
        "else this Python (default)",
    )
    parser.add_argument("--board-id", default="53494d424f415244", help="the board's id, 16 hex digits")
    parser.add_argument(
        "--plant",
        type=argparse.FileType("r"),
        help="JSON object of plant parameters (a hidden leg, for tests)",
    )
    parser.add_argument(
        "--config",
        type=argparse.FileType("r"),
        help="JSON object of firmware settings, as a board's config.json (docs/legs-build.md)",
    )
    args = parser.parse_args(argv)
    try:
        faults = tuple(FaultSpec.parse(f) for f in args.fault)
    except ValueError as exc:
        parser.error(str(exc))
    if args.speed <= 0:
        parser.error("--speed must be positive")
    try:
        board_id = bytes.fromhex(args.board_id)
    except ValueError:
        board_id = b""
    if len(board_id) != 8:
        parser.error(f"--board-id must be 16 hex digits, got {args.board_id!r}")
    plant = _json_object(parser, "--plant", args.plant, "plant parameters")
    config = _json_object(parser, "--config", args.config, "firmware settings")
    server = BoardServer(
        link=args.link,
        control=args.control,
        speed=args.speed,
        status_period_ms=args.status_ms,
        angle_stop=not args.no_angle_stop,
        faults=faults,
        seed=args.seed,
        clock=args.clock,
        runtime=args.runtime,
        board_id=board_id,
        plant=plant,
        config=config,
    )

    def stop(_signum: int, _frame: object) -> None:
        server.running = False

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    watch_parent()  # a launcher that dies takes its simulator with it
    try:
        pty = server.open()
    except (RuntimeChoiceError, ValueError, RuntimeError) as exc:
        print(f"legboard: {exc}", file=sys.stderr)
        server.close()
        return 2
    print(
        f"legboard ready pty={pty} link={server.link or ''} "
        f"control={server.control_path or ''} speed={args.speed:g} clock={args.clock} "
        f"runtime={server.runner.name}",
        flush=True,
    )
    try:
        server.serve_forever()
    except RuntimeError as exc:  # the firmware's process ended or hangs
        print(f"legboard: {exc}", file=sys.stderr)
        return 1
    finally:
        server.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
