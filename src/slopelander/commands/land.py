"""``slopelander land``: one landing on a real (or simulated) vehicle from the companion.

Every argument is checked before the autopilot is contacted: the connection string's form, the
slope against the lookup table, the output folder, the calibration, and the leg board itself (it
is opened once and asked what it is: a real board flies only with a measured calibration). The
landing is the one flight path (:class:`slopelander.controller.session.Session`); the state changes
are printed as they happen, and every landing leaves its evidence in a folder of its own: the
MAVLink telemetry log, the transitions, the slope estimate, the outcome and, where matplotlib is
installed, a picture. ``--check`` runs every check and talks to the board and the autopilot
without flying.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import IO

from slopelander.commands.options import renamed
from slopelander.errors import SlopelanderError
from slopelander.outputs import check_output_dir

NETWORK_SCHEMES = ("tcp", "tcpin", "udp", "udpin", "udpout", "udpbcast")
"""pymavlink's network connection strings (``mavutil.mavlink_connection``): SCHEME:HOST:PORT."""

#: the companion's serial link to the autopilot: ``SERIAL2_BAUD 921`` in the shipped
#: firmware_params/f450-fsa.parm (921600 baud; tests/cli/test_land_args.py holds the two equal)
DEFAULT_BAUD = 921600

#: exit codes (docs/commands.md): 0 landed (or --check passed), 1 an argument or a check refused,
#: 3 the landing did not end LANDED (aborted, refused in flight, left on the roof), 130 interrupted
EXIT_LANDED, EXIT_REFUSED, EXIT_NOT_LANDED = 0, 1, 3
#: local seconds ``--check`` listens for the on-board script's once-a-second SL_VER
SCRIPT_WAIT_S = 5.0

CONNECT_FORMS = (
    "tcp:HOST:PORT, tcpin:HOST:PORT, udpin:HOST:PORT, udpout:HOST:PORT, udpbcast:HOST:PORT, "
    "udp:HOST:PORT (= udpin), or a serial device such as /dev/ttyACM0 (with --baud)"
)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "land",
        help="land on a slope: preset the legs, descend, reflex, disarm",
        description="Fly one landing from the companion computer: measure the slope (a survey pass "
        "when needed), choose the legs' preset from the lookup table (or the pilot's switch), set "
        "the legs, descend at 0.5 m/s, let the on-board script cut the motors at 30 cm and reverse "
        "them at impact, and disarm once still. The vehicle must hover in GUIDED over the landing "
        "spot within the rangefinder's reach. Writes the telemetry log, the transitions, the slope "
        "estimate, the outcome and a picture into --out. Exit codes: 0 landed (or --check passed), "
        "1 refused before flying, 3 not landed, 130 interrupted.",
    )
    p.add_argument(
        "--connect",
        required=True,
        metavar="CONNECTION",
        help="the autopilot's MAVLink connection: tcp:HOST:PORT, tcpin:HOST:PORT, udpin:HOST:PORT, "
        "udpout:HOST:PORT or a serial device (/dev/ttyAMA0, with --baud)",
    )
    p.add_argument(
        "--baud",
        type=int,
        help=f"baud rate of a serial --connect device (default {DEFAULT_BAUD}: SERIAL2_BAUD 921 "
        "in the shipped f450-fsa.parm)",
    )
    p.add_argument(
        "--legs-port",
        required=True,
        metavar="DEVICE",
        help="the leg board's serial device, e.g. /dev/ttyACM1",
    )
    p.add_argument(
        "--slope",
        type=slope_arg,
        help="slope of the landing site, deg (within the lookup table's slopes: 0..60 for the shipped one), "
        "checked against the slope the companion measures; or 'auto': land on the measured slope "
        "(docs/slope-estimate.md). Required unless --check",
    )
    p.add_argument("--table", help="lookup table file (YAML); default: the shipped table")
    p.add_argument("--config", help="controller settings (YAML) overriding the shipped defaults")
    p.add_argument(
        "--calibration",
        metavar="FILE",
        help="the leg board's measured current-to-torque calibration (YAML, docs/legs-build.md); "
        "required for a real board, the simulated board may fly the shipped assumed curve",
    )
    p.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="folder for this landing's evidence (default: landing-YYYYMMDD-HHMMSS in the current folder)",
    )
    p.add_argument("--record", action=_Renamed, help=argparse.SUPPRESS)
    renamed(p, "--legs", "--legs-port")
    p.add_argument(
        "--lockstep",
        action="store_true",
        help="the autopilot is a simulator that waits for the companion's time echo (the simulated "
        "vehicle's --lockstep); never for a real vehicle",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="check the settings, the table, the calibration, the leg board and the autopilot; do not fly",
    )
    p.add_argument(
        "--timeout", type=float, default=120.0, help="give up (abort) after this many s (default 120)"
    )
    p.set_defaults(handler=run)


class _Renamed(argparse.Action):
    """``--record FILE`` wrote the transitions alone; every landing now writes its folder."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:  # type: ignore[override]
        parser.error(
            f"--record {values}: every landing now writes its evidence into a folder of its own; "
            "name it with --out DIR (the transitions are DIR/transitions.jsonl)"
        )


def slope_arg(text: str) -> float | str:
    """``--slope``: 'auto' or a number of degrees (range-checked in :func:`run`)."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of degrees or 'auto', got {text!r}") from None


def connection_string(text: str, baud: int | None) -> str:
    """The pymavlink string for ``--connect``/``--baud``, or a one-line error naming the forms."""
    text = text.strip()
    bad = SlopelanderError(f"--connect {text!r} is not a MAVLink connection; use {CONNECT_FORMS}")
    scheme, _, rest = text.partition(":")
    if scheme in NETWORK_SCHEMES or re.fullmatch(r"[\w.-]+:\d+", text):
        host, _, port = (rest if scheme in NETWORK_SCHEMES else text).rpartition(":")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise bad
        if baud is not None:
            raise SlopelanderError(f"--baud is for a serial device, not for --connect {text}")
        return text
    device, comma, rate = text.partition(",")
    if not (device.startswith("/dev/") or re.fullmatch(r"COM\d+", device, re.IGNORECASE)):
        raise bad
    if comma and (not rate.isdigit() or baud is not None):
        raise SlopelanderError(f"--connect {text!r}: give the baud rate with --baud only")
    speed = baud if baud is not None else int(rate) if comma else DEFAULT_BAUD
    if speed is not None and speed <= 0:
        raise SlopelanderError(f"--baud must be a positive number, got {speed}")
    if device.startswith("/dev/") and not Path(device).exists():
        raise SlopelanderError(f"--connect {device}: no such device")
    return device if speed is None else f"{device},{speed}"


class LiveTransitions:
    """Where the state machine writes each transition (a JSON line): printed at once, and copied
    to the ``--record`` file when there is one."""

    def __init__(self, record: IO[str] | None = None, out: IO[str] | None = None) -> None:
        self.record = record
        self.out = out or sys.stdout

    def write(self, text: str) -> int:
        if self.record is not None:
            self.record.write(text)
        for line in text.splitlines():
            with_keys = json.loads(line) if line.strip() else {}
            if "to" in with_keys:
                print(format_transition(with_keys), file=self.out, flush=True)
        return len(text)

    def flush(self) -> None:
        if self.record is not None:
            self.record.flush()


def format_transition(h: dict) -> str:
    return f"{h['t']:9.3f} s  {h['from'] or '-':>9} -> {h['to']:<9} {h['reason']}"


def run(args: argparse.Namespace) -> int:
    auto = args.slope == "auto"
    if args.slope is None and not args.check:
        raise SlopelanderError("--slope is required (a number of degrees, or 'auto'), unless --check")
    if args.slope is not None and not auto and not (math.isfinite(args.slope) and 0 <= args.slope < 90):
        raise SlopelanderError(f"--slope must be within 0..89 deg, got {args.slope:g}")
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        raise SlopelanderError(f"--timeout must be a positive number of seconds, got {args.timeout:g}")
    url = connection_string(args.connect, args.baud)
    out = None
    if not args.check:
        out = args.out or Path(time.strftime("landing-%Y%m%d-%H%M%S", time.gmtime()))
        check_output_dir(out, "--out")

    from slopelander.controller.config import load_config
    from slopelander.controller.leg_checks import calibration_problems
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable
    from slopelander.legs.calibration import load_calibration
    from slopelander.legs.driver import LegBoard

    cfg = load_config(args.config)
    table = LookupTable.load(args.table or DEFAULT_TABLE)
    lo, hi = table.slope_range
    if args.slope is not None and not auto and not lo <= args.slope <= hi:
        raise SlopelanderError(
            f"--slope {args.slope:g} is outside the lookup table's slopes {lo:g}..{hi:g} deg "
            f"({args.table or 'the shipped table'})"
        )
    if "://" not in args.legs_port and not Path(args.legs_port).exists():  # pyserial also takes URLs
        raise SlopelanderError(f"--legs-port {args.legs_port}: no such device (is the leg board plugged in?)")
    calibration = load_calibration(args.calibration)
    with LegBoard.open(args.legs_port, calibration=calibration) as probe:  # what board is it?
        simulated = probe.info is not None and probe.info.simulated
        board = probe.info
    if simulated and not pseudo_terminal(args.legs_port):
        raise SlopelanderError(
            f"--legs-port {args.legs_port}: a board on a real serial device reports itself SIMULATED; a "
            "simulated board runs on a pseudo-terminal. Refusing to trust it (wrong firmware flashed?)"
        )
    for problem in calibration_problems(board, calibration, given=args.calibration is not None):
        raise SlopelanderError(problem)
    if calibration.assumed:
        print(f"(simulated leg board: torques through the ASSUMED calibration {calibration.source})")
    if args.check:
        return check(args, url, cfg, table, calibration, board)
    out.mkdir(parents=True, exist_ok=True)
    return _fly(args, url, out, cfg, table, calibration)


def pseudo_terminal(port: str) -> bool:
    """Whether ``port`` is a pseudo-terminal (where the simulated board lives; Linux gives their
    slave ends major device numbers 136-143), not a USB or UART serial device."""
    import os
    import stat

    if "://" in port:  # a pyserial URL (socket://, rfc2217://): not a device of this machine
        return False
    try:
        st = os.stat(os.path.realpath(port))
    except OSError:
        return False
    return stat.S_ISCHR(st.st_mode) and 136 <= os.major(st.st_rdev) <= 143


def check(args: argparse.Namespace, url: str, cfg, table, calibration, board) -> int:
    """``--check``: every check a landing makes before it flies, the autopilot and the board
    asked what they are; nothing is commanded (no stream but the landing's, no leg moved)."""
    from slopelander.controller.leg_checks import preflight
    from slopelander.controller.session import Session, SessionError
    from slopelander.controller.states.base import SCRIPT_CONTRACT
    from slopelander.legs.errors import LegBoardError

    lo, hi = table.slope_range
    print(f"settings: {args.config or 'shipped defaults'}: ok")
    print(f"table: {args.table or 'shipped'}: slopes {lo:g}..{hi:g} deg, ok")
    print(f"calibration: {calibration.source} ({calibration.provenance})")
    print(
        f"leg board {args.legs_port}: protocol {board.version}, {board.legs} legs"
        + (", simulated" if board.simulated else "")
        + (", sets leg angles" if board.angle_stop else ", leg angles set by hand")
    )
    problems = []
    session = Session(url, cfg, table=table, calibration=calibration, telemetry=False, lockstep=args.lockstep)
    try:
        info = session.connect()
        end = time.monotonic() + SCRIPT_WAIT_S  # it says SL_VER once a second of vehicle time
        while info.script_version is None and time.monotonic() < end:
            session.link.poll()
            time.sleep(0.01)
        print(f"autopilot: {info.describe()}")
        hb = session.link.last.get("HEARTBEAT")
        if hb is not None:
            from slopelander.controller.link import mavlink
            from slopelander.controller.runner import MODE_NAMES

            armed = "armed" if hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED else "disarmed"
            mode = MODE_NAMES.get(hb.custom_mode, f"number {hb.custom_mode}")
            print(f"autopilot now: mode {mode}, {armed} (a landing starts hovering in GUIDED)")
        version = info.script_version
        if version is None:
            problems.append("the on-board script is silent (no SL_VER): load it (firmware_params/README.md)")
        elif int(version) != SCRIPT_CONTRACT:
            problems.append(f"on-board script v{version:g}, this companion needs v{SCRIPT_CONTRACT}")
        legs = session.open_legs(args.legs_port)
        status = legs.query()
        print("legs: angles " + ", ".join(f"{lg.angle_deg:.1f}" for lg in status.legs) + " deg")
        problems += preflight(legs, status, table=args.table)  # what `legs status --calibration` says
    except (SessionError, LegBoardError) as exc:
        problems.append(str(exc))
    finally:
        session.close()
    for p in problems:
        print(f"not ready: {p}")
    print("ready to fly" if not problems else f"{len(problems)} problem(s): not ready to fly")
    return EXIT_LANDED if not problems else EXIT_REFUSED


def _fly(args: argparse.Namespace, url: str, out: Path, cfg, table, calibration) -> int:
    from slopelander.controller.session import Session
    from slopelander.controller.telemetry import landing_figures

    session = Session(url, cfg, table=table, calibration=calibration, out=out, lockstep=args.lockstep)
    print(f"evidence of this landing: {out}/", flush=True)
    end = "ABORTED"
    history: list[dict] = []
    outcome: dict = {"slope_arg": args.slope}
    interrupts = PilotInterrupts()
    try:
        with interrupts:  # from the first word to the autopilot: a survey pass flies the vehicle too
            try:
                return _land(args, session, outcome, interrupts, history)
            except PilotInterruptedError:
                held = session.hand_to_loiter()
                outcome["outcome"] = end = "INTERRUPTED"
                print("the autopilot holds position in LOITER" if held else "LOITER not seen: take over")
                return 130
    finally:
        if interrupts.lander is not None:
            history[:] = list(interrupts.lander.machine.history)
        session.close()
        tele = session.telemetry
        if history and tele is not None:
            impact, slide, pitch = landing_figures(tele, history, cfg["reflex.impact_threshold_mps2"])
            outcome.update(impact_mps=impact, slide_m=slide, min_pitch_deg=pitch)
            _picture(out, tele, history, outcome)
        outcome.setdefault("outcome", end)
        outcome["transitions"] = history
        (out / "result.json").write_text(json.dumps(outcome, indent=1, default=str))
        print(f"transitions: {out / 'transitions.jsonl'}; telemetry log: {out / 'flight.tlog'}", flush=True)
        print(f"outcome: {outcome['outcome']}", flush=True)


def _land(
    args: argparse.Namespace, session, outcome: dict, interrupts: PilotInterrupts, history: list
) -> int:
    """Connect, measure the slope, plan, open the legs and land; the exit code."""
    from slopelander.controller.landing import angle_instruction

    link = session.link
    tick = lambda: (link.poll(), interrupts.check())  # noqa: E731
    info = session.connect()
    print(f"autopilot: {info.describe()}")
    interrupts.check()
    slope = session.measure_slope(args.slope, tick=tick)
    interrupts.check()
    outcome["slope_deg"] = slope.slope_deg
    if slope.slope_deg is None:
        outcome.update(outcome="REFUSED", why=slope.refusal)
        return EXIT_NOT_LANDED
    preset, speed = session.plan(slope.slope_deg)
    outcome.update(preset=asdict(preset), expected_impact_mps=speed)
    up, down = preset.tau_up, preset.tau_down
    angle = "" if preset.angle_up_deg is None else f", uphill angle {preset.angle_up_deg:.1f} deg"
    print(
        f"expected impact {speed:.2f} m/s on {slope.slope_deg:.1f} deg; "
        f"legs {up:.2f}/{down:.2f} N*m{angle} ({preset.source})"
    )
    legs = session.open_legs(args.legs_port)
    interrupts.check()
    todo = angle_instruction(preset.angle_up_deg, legs.info.angle_stop)
    if todo is not None:
        print(todo)
        link.send_statustext(f"SL set uphill legs to {preset.angle_up_deg:.1f} deg")
    lander = session.make_lander(preset, slope_deg=slope.slope_deg, record=LiveTransitions(), slope=slope)
    interrupts.lander = lander
    end = lander.run(args.timeout, interrupts=interrupts)
    history[:] = list(lander.machine.history)
    left = session.settle()
    if left:
        print(f"warning: {left} command(s) to the autopilot unanswered at exit", flush=True)
    if end == "SETTLED":  # ended on the roof, armed, motors held: said, not hidden
        print(
            "the vehicle is ARMED on the roof with its motors held stopped by the on-board script; "
            "it disarms itself once still (the companion is silent now): stay clear",
            flush=True,
        )
    outcome["outcome"] = end
    return EXIT_LANDED if end == "LANDED" else EXIT_NOT_LANDED


def _picture(out: Path, tele, history: list[dict], outcome: dict) -> None:
    """The flight's picture, where matplotlib is installed (a companion with the core alone has
    none: the telemetry log holds everything it is drawn from)."""
    try:
        from slopelander.plots.flight import plot_flight
    except ModuleNotFoundError:
        print("no picture: matplotlib is not installed here (pip install 'slopelander[sim]')")
        return
    slope = outcome.get("slope_deg")
    title = f"slopelander land: {slope:g} deg - {outcome.get('outcome')}" if slope else "slopelander land"
    path = plot_flight(tele, history, out / "flight.png", title=title)
    print(f"picture: {path}")


class PilotInterrupts:
    """Ctrl-C (SIGINT) and SIGTERM during a landing are counted, not raised: what an interrupt
    does depends on the landing's state (:meth:`slopelander.controller.runner.Lander.interrupt`),
    and a KeyboardInterrupt thrown out of the middle of a step would leave the vehicle wherever
    it was. Each one is answered with a line saying what happens now."""

    def __init__(self, lander=None) -> None:
        #: the landing's controller, once made; before it (connecting, the survey pass, the plan)
        #: an interrupt stops the flight where it is (:meth:`check`)
        self.lander = lander
        self.count = 0
        self._old: dict[int, object] = {}

    def _on_signal(self, signum: int, frame: object) -> None:
        self.count += 1
        if self.lander is None:
            print("interrupted before the landing: holding position in LOITER", flush=True)
            return
        state = self.lander.machine.name if self.lander.machine._started else "PRESET"
        if state in ("CUT", "REVERSE", "SETTLED") and self.count == 1:
            what = "on the roof with the motors held: finishing the landing to its disarm (again to leave)"
        elif state in ("CUT", "REVERSE", "SETTLED"):
            what = "leaving the vehicle to the on-board script, which disarms it once still"
        elif state in ("LANDED", "READY", "ABORTED", "ESTOP"):
            what = "ending"
        else:
            what = "aborting the landing: the autopilot holds position in LOITER"
        print(f"interrupted in {state}: {what}", flush=True)

    def __call__(self) -> int:
        return self.count

    def check(self) -> None:
        """Raise :class:`PilotInterruptedError` if the pilot interrupted before the landing began."""
        if self.count and self.lander is None:
            raise PilotInterruptedError()

    def __enter__(self) -> PilotInterrupts:
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._old[sig] = signal.signal(sig, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


class PilotInterruptedError(Exception):
    """The pilot interrupted before the landing's controller took over (the survey, the plan)."""
