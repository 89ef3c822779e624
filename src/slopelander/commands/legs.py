"""``slopelander legs ...``: thin command-line wrappers over the leg-board driver."""

from __future__ import annotations

import argparse

from slopelander.commands.options import renamed
from slopelander.legs.driver import BoardStatus, LegBoard, LegResult, PairMap
from slopelander.legs.messages import N_LEGS

ANGLE_MAX_DEG = 37.5  # fully extended leg (paper Sec. III)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "legs",
        help="talk to the leg board (status, calibrate, set, loosen, angle)",
        description="Talk to the leg board over its serial device. Exit codes: 0 done, 1 an error "
        "(or, for status --calibration, not ready to fly), 2 a usage error or nothing to set, "
        "130 interrupted.",
    )
    sub = parser.add_subparsers(dest="legs_command", metavar="ACTION", required=True)

    def port(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--legs-port",
            required=True,
            metavar="DEVICE",
            help="the leg board's serial device, e.g. /dev/ttyACM0",
        )
        p.add_argument(
            "--legs-baud",
            type=int,
            default=115200,
            help="its baud rate (default 115200; USB serial ignores it)",
        )
        renamed(p, "--port", "--legs-port")
        renamed(p, "--baud", "--legs-baud")

    def common(p: argparse.ArgumentParser) -> None:
        port(p)
        p.add_argument("--calibration", help="calibration file (default: shipped, assumed)")
        p.add_argument("--timeout", type=float, default=20.0, help="seconds (default 20)")

    def pairs(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--uphill-legs", type=_leg_list, default=(0, 1), help="legs of the uphill pair (default 0,1)"
        )
        p.add_argument(
            "--downhill-legs", type=_leg_list, default=(2, 3), help="legs of the downhill pair (default 2,3)"
        )

    p = sub.add_parser(
        "status",
        help="print the board and each leg's state, current, torque and angle; with "
        "--calibration, check board, calibration and lookup table before a flight",
        description="Print the board and each leg's state, current, torque and angle. With "
        "--calibration, also check that the board, the calibration and the lookup table agree "
        "before a flight (exit code 1 when they do not).",
    )
    common(p)
    p.add_argument(
        "--table",
        metavar="FILE",
        help="lookup table whose presets must be in the calibration (default: shipped)",
    )
    p.set_defaults(handler=_status)

    p = sub.add_parser(
        "calibrate",
        help="measure each leg's current-to-torque curve on the bench and write a calibration file",
        description="Bench procedure: docs/legs-build.md, section Calibration.",
    )
    port(p)
    p.add_argument(
        "--masses", required=True, type=_masses, help="masses on the levers, kg, e.g. 0.2,0.45,0.7"
    )
    p.add_argument("--lever", required=True, type=float, help="lever length, joint axis to the mass, m")
    p.add_argument("--lever-moment", type=float, default=0.0, help="the bare lever's torque at the mark, N·m")
    p.add_argument("--repeats", type=int, default=3, help="runs over every mass (default 3)")
    p.add_argument("--step", type=int, default=2, help="current step of the search, mA (default 2)")
    p.add_argument("--out", required=True, help="calibration file to write (YAML)")
    p.add_argument(
        "--bench",
        default="prompt",
        metavar="prompt|sim:CONTROL",
        help="who moves the pegs: prompt = you, asked at each step (default); sim:PATH = a simulated "
        "board's control socket",
    )
    p.set_defaults(handler=_calibrate)

    p = sub.add_parser(
        "set",
        help="set friction torques (N·m per joint) and wait",
        description="Set the friction torques of the uphill and downhill pairs (or of single legs, "
        "or from the lookup table) and wait until each leg holds its torque.",
    )
    common(p)
    pairs(p)
    p.add_argument("--tau-up", type=float, help="uphill pair torque, N·m")
    p.add_argument("--tau-down", type=float, help="downhill pair torque, N·m")
    p.add_argument(
        "--leg",
        type=_leg_value,
        action="append",
        default=[],
        metavar="I=NM",
        help="one leg's torque, e.g. --leg 2=1.7 (repeatable)",
    )
    p.add_argument("--tolerance", type=float, default=0.1, help="N·m (default 0.1)")
    p.add_argument(
        "--table",
        nargs="?",
        const="default",
        metavar="FILE",
        help="take the torques from a lookup table (no FILE: the shipped one); needs --slope and --speed",
    )
    p.add_argument("--slope", type=float, help="landing slope for --table, deg")
    p.add_argument("--speed", type=float, help="vertical impact speed for --table, m/s")
    renamed(p, "--uphill", "--tau-up")
    renamed(p, "--downhill", "--tau-down")
    p.set_defaults(handler=_set, up="tau_up", down="tau_down")

    p = sub.add_parser(
        "loosen",
        help="loosen all legs so the springs reset them",
        description="Loosen every leg's friction so that the springs bring the legs back to rest.",
    )
    common(p)
    p.set_defaults(handler=_loosen)

    p = sub.add_parser(
        "angle",
        help="set leg rest angles (degrees, 0..37.5)",
        description="Set the legs' rest angles (boards with angle stops), per pair or per leg.",
    )
    common(p)
    pairs(p)
    p.add_argument("--angle-up", type=_angle_deg, help="uphill pair angle, degrees")
    p.add_argument("--angle-down", type=_angle_deg, help="downhill pair angle, degrees")
    p.add_argument(
        "--leg",
        type=_leg_value,
        action="append",
        default=[],
        metavar="I=DEG",
        help="one leg's angle (repeatable)",
    )
    renamed(p, "--uphill", "--angle-up")
    renamed(p, "--downhill", "--angle-down")
    p.set_defaults(handler=_angle, up="angle_up", down="angle_down")


def _leg_list(text: str) -> tuple[int, ...]:
    try:
        legs = tuple(int(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected leg indices like 0,1: {text!r}") from None
    if not all(0 <= i < N_LEGS for i in legs):
        raise argparse.ArgumentTypeError(f"legs are 0..{N_LEGS - 1}: {text!r}")
    return legs


def _leg_value(text: str) -> tuple[int, float]:
    leg, sep, value = text.partition("=")
    try:
        out = int(leg), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LEG=VALUE, e.g. 2=1.7: {text!r}") from None
    if not sep or not 0 <= out[0] < N_LEGS:
        raise argparse.ArgumentTypeError(f"expected LEG=VALUE with LEG 0..{N_LEGS - 1}")
    return out


def _open(args: argparse.Namespace) -> LegBoard:
    pairs = PairMap(getattr(args, "uphill_legs", (0, 1)), getattr(args, "downhill_legs", (2, 3)))
    return LegBoard.open(
        args.legs_port,
        args.legs_baud,
        calibration=args.calibration,
        pairs=pairs,
        timeout=min(args.timeout, 5.0),
    )


def _per_leg(args: argparse.Namespace, board: LegBoard) -> dict[int, float]:
    values: dict[int, float] = {}
    for pair, dest in (("uphill", args.up), ("downhill", args.down)):
        if getattr(args, dest) is not None:
            values.update(dict.fromkeys(board.pairs.legs(pair), getattr(args, dest)))
    values.update(dict(args.leg))
    return values


def format_status(status: BoardStatus) -> str:
    lines = [f"board time {status.board_time_s:.1f} s"]
    for s in status.legs:
        torque = "   -  " if s.torque_nm is None else f"{s.torque_nm:5.2f} "
        fault = f"  fault: {s.fault.name}" if s.fault else ""
        lines.append(
            f"leg {s.leg}  {s.state.name:<11} {s.current_ma:5d} mA (target {s.target_ma:4d})"
            f"  ≈{torque}N·m  {s.angle_deg:5.1f}°{fault}"
        )
    return "\n".join(lines)


def format_results(results: dict[int, LegResult], unit: str) -> str:
    lines = []
    for r in results.values():
        angle = "" if unit == "°" else f", {r.angle_deg:.1f}°"
        lines.append(
            f"leg {r.leg}  {r.achieved:6.2f} {unit}  ({r.current_ma:.0f} mA{angle}, "
            f"{r.board_seconds:.1f} s board time)"
        )
    return "\n".join(lines)


def _status(args: argparse.Namespace) -> int:
    """The board's status; with ``--calibration``, every check a flight makes of the legs."""
    from slopelander.controller.leg_checks import preflight

    with _open(args) as board:
        status = board.query(timeout=min(args.timeout, 5.0))
        info = board.info
        print(
            f"board {info.board_id}  firmware {info.firmware}  protocol {info.version}  "
            f"{'simulated' if info.simulated else 'real'}  "
            f"{'angle stops' if info.angle_stop else 'no angle stops'}"
        )
        print(format_status(status))
        if args.calibration is None:
            if board.calibration.assumed:
                print(f"(torques from an ASSUMED calibration: {board.calibration.source})")
            return 0
        problems = preflight(board, status, table=args.table)
    for line in problems:
        print(f"NOT READY: {line}")
    if problems:
        return 1
    print(f"ready: board, calibration {board.calibration.source} and the lookup table agree")
    return 0


def _masses(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected masses in kg like 0.2,0.45,0.7: {text!r}") from None


def _calibrate(args: argparse.Namespace) -> int:
    """The bench procedure, the fit, the file; or the reasons it cannot be flown on."""
    from pathlib import Path

    import yaml

    from slopelander.errors import SlopelanderError
    from slopelander.legs import calibrate as cal
    from slopelander.legs.bench import PromptBench, simulated_bench

    try:
        proc = cal.Procedure(
            tuple(args.masses), args.lever, args.lever_moment, repeats=args.repeats, step_ma=args.step
        )
    except ValueError as exc:
        raise SlopelanderError(str(exc)) from None
    out = Path(args.out)
    if out.exists():
        raise SlopelanderError(f"--out {out} exists: give a new file name (a calibration is a record)")
    if args.bench == "prompt":
        bench = PromptBench()
    elif args.bench.startswith("sim:"):
        bench = simulated_bench(args.bench[4:])
    else:
        raise SlopelanderError(f"--bench must be prompt or sim:CONTROL_SOCKET, not {args.bench!r}")
    board = LegBoard.open(args.legs_port, args.legs_baud, status_period_ms=20, timeout=5.0)
    try:
        board.set_clock(bench.clock)
        if hasattr(bench, "driver"):  # a simulated board's bench steps the driver between its waits
            bench.driver = board
        points = cal.measure(board, bench, proc, board.calibration)
        try:
            fits = cal.fit_all(points, proc)
        except cal.CalibrationRefused:
            rejected = out.with_name(out.name + ".rejected")
            fits = [cal.fit_leg(leg, points, proc) for leg in range(N_LEGS)]
            rejected.write_text(
                yaml.safe_dump(cal.document(fits, proc, board.info.board_id, board.info.firmware))
            )
            print(f"(the measurements are in {rejected}; not a calibration to fly on)")
            raise
        doc = cal.document(fits, proc, board.info.board_id, board.info.firmware)
    finally:
        bench.finish()
        board.close()
    header = (
        "# Leg-board calibration: static friction torque of each joint vs motor current.\n"
        "# PROVENANCE: MEASURED with `slopelander legs calibrate` (docs/legs-build.md).\n"
    )
    out.write_text(header + yaml.safe_dump(doc, sort_keys=False))
    for f in fits:
        c = f.coeffs
        terms = " ".join(f"{v:+.3f}·τ^{k}" for k, v in enumerate(c))
        print(
            f"leg {f.leg}: current = {terms} mA over {f.torque_range[0]:.2f}–{f.torque_range[1]:.2f} N·m; "
            f"±{f.uncertainty_nm:.3f} N·m (95 %), points {f.residual_rms_nm:.3f} N·m rms, "
            f"spread {f.spread_ma:.0f} mA"
        )
    print(f"wrote {out} (provenance measured, board {board.info.board_id})")
    return 0


def _from_table(args: argparse.Namespace) -> None:
    """Fill --tau-up/--tau-down from the lookup table, before the board is opened."""
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable
    from slopelander.errors import SlopelanderError

    if args.slope is None or args.speed is None:
        raise SlopelanderError("--table needs --slope and --speed")
    if args.tau_up is not None or args.tau_down is not None or args.leg:
        raise SlopelanderError("give either --table or torques (--tau-up/--tau-down/--leg), not both")
    path = DEFAULT_TABLE if args.table == "default" else args.table
    p = LookupTable.load(path).lookup(args.slope, args.speed)
    args.tau_up, args.tau_down = p.tau_up, p.tau_down
    print(
        f"table {path}: {args.slope:g} deg, {args.speed:g} m/s -> uphill {p.tau_up:.2f} N·m, "
        f"downhill {p.tau_down:.2f} N·m; set the uphill legs to {p.angle_up_deg:.1f}° "
        f"(model predicts {p.outcome})"
    )


def _set(args: argparse.Namespace) -> int:
    if args.table is not None:
        _from_table(args)
    with _open(args) as board:
        if board.calibration.assumed:
            print(f"(torques through an ASSUMED calibration: {board.calibration.source})")
        torques = _per_leg(args, board)
        if not torques:
            print("nothing to set: give --tau-up, --tau-down or --leg")
            return 2
        results = board.wait(board.start_torques(torques, timeout=args.timeout, tolerance_nm=args.tolerance))
        print(format_results(results, "N·m"))
    return 0


def _loosen(args: argparse.Namespace) -> int:
    with _open(args) as board:
        print(format_results(board.loosen_all(timeout=args.timeout), "°"))
    return 0


def _angle_deg(text: str) -> float:
    """A leg rest angle within the joint's travel, refused before the board is opened."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of degrees") from None
    if not 0.0 <= v <= ANGLE_MAX_DEG:
        raise argparse.ArgumentTypeError(f"{v:g} deg is outside the legs' travel 0..{ANGLE_MAX_DEG:g} deg")
    return v


def _angle(args: argparse.Namespace) -> int:
    with _open(args) as board:
        angles = _per_leg(args, board)
        if not angles:
            print("nothing to set: give --angle-up, --angle-down or --leg")
            return 2
        print(format_results(board.set_leg_angles(angles, timeout=args.timeout), "°"))
    return 0
