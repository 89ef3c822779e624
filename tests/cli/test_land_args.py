"""``slopelander land``: every argument checked before the autopilot is contacted, a real leg board
flown only with a measured calibration, the state changes printed as they happen, every landing's
evidence in a folder of its own, ``--check`` without flying -- against real processes (the
simulated vehicle and leg board, and a board that answers as a real one does)."""

from __future__ import annotations

import dataclasses
import os
import socket
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}


def land(*args: str, cwd: Path | None = None, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    """``land`` run from ``cwd`` (a new temporary folder by default: a landing writes its evidence
    folder into the current one)."""
    if cwd is None:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            return land(*args, cwd=Path(tmp), timeout=timeout)
    return subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "land", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=ENV,
        cwd=cwd,
    )


def free_udp() -> str:
    """A UDP port nobody sends to: an autopilot that never answers (the wait for it is 10 s)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return f"udpin:127.0.0.1:{port}"


def one_line(out: subprocess.CompletedProcess[str]) -> str:
    assert out.returncode == 1, out.stdout + out.stderr
    assert "Traceback" not in out.stderr and out.stderr.count("\n") == 1, out.stderr
    return out.stderr


@pytest.mark.parametrize(
    ("connect", "named"),
    [
        ("garbage:foo", "tcp:HOST:PORT"),
        ("tcp:127.0.0.1", "tcp:HOST:PORT"),
        ("udpin:0.0.0.0:99999", "udpin:HOST:PORT"),
        ("/dev/no-such-tty", "no such device"),
    ],
)
def test_a_connection_string_of_no_known_form_names_the_forms(connect: str, named: str) -> None:
    err = one_line(land("--connect", connect, "--legs-port", "/dev/null", "--slope", "35"))
    assert named in err and "invalid literal" not in err


def test_baud_is_for_a_serial_device_only() -> None:
    err = one_line(
        land(
            "--connect", "tcp:127.0.0.1:5760", "--baud", "57600", "--legs-port", "/dev/null", "--slope", "35"
        )
    )
    assert "--baud is for a serial device" in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--slope", "70"], "--slope 70 is outside the lookup table's slopes 0..60 deg"),
        (["--slope", "35", "--out", "nope/landing"], "folder nope does not exist"),
        (["--slope", "35", "--out", "/proc/landing"], "folder /proc is not writable"),
    ],
)
def test_arguments_are_refused_before_the_autopilot_is_waited_for(args: list[str], message: str) -> None:
    t0 = time.monotonic()
    err = one_line(land("--connect", free_udp(), "--legs-port", "/dev/null", *args))
    assert message in err
    assert time.monotonic() - t0 < 8.0  # the wait for an autopilot alone is 10 s


def test_only_a_pseudo_terminal_may_hold_a_simulated_board() -> None:
    """A board that says SIMULATED is trusted with the assumed calibration only on a
    pseudo-terminal, where the simulator lives; on a real serial device (here the character
    device /dev/null stands for one) the claim is refused before anything flies."""
    import os

    from slopelander.commands.land import pseudo_terminal

    main, sub = os.openpty()
    try:
        assert pseudo_terminal(os.ttyname(sub))
    finally:
        os.close(main)
        os.close(sub)
    assert not pseudo_terminal("/dev/null")
    assert not pseudo_terminal("/no/such/device")
    assert not pseudo_terminal("socket://127.0.0.1:5000")


def test_the_old_record_option_is_refused_with_its_new_name() -> None:
    out = land("--connect", free_udp(), "--legs-port", "/dev/null", "--slope", "35", "--record", "x.jsonl")
    assert out.returncode == 2 and "name it with --out DIR" in out.stderr, out.stderr


def test_the_default_baud_is_the_shipped_parameter_files() -> None:
    """The companion's serial link runs at SERIAL2_BAUD of the shipped parameter file (ArduPilot's
    code 921 is 921600 baud): a serial --connect without --baud meets the autopilot at its rate."""
    import re

    from slopelander.commands.land import DEFAULT_BAUD, connection_string

    parm = (ROOT / "firmware_params" / "f450-fsa.parm").read_text()
    code = int(re.search(r"^SERIAL2_BAUD\s+(\d+)", parm, re.MULTILINE).group(1))
    assert {921: 921600, 115: 115200, 57: 57600}[code] == DEFAULT_BAUD
    assert connection_string("/dev/null", None) == f"/dev/null,{DEFAULT_BAUD}"


def test_land_help_points_to_the_page_that_describes_the_calibration_file() -> None:
    """A pilot reading ``land --help`` for ``--calibration`` is sent to the page with the file's keys."""
    import re

    from slopelander.cli import build_parser

    land_parser = build_parser("land")._subparsers._group_actions[0].choices["land"]
    (option,) = [a for a in land_parser._actions if "--calibration" in a.option_strings]
    (page,) = re.findall(r"docs/[\w-]+\.md", option.help)
    text = (ROOT / page).read_text()
    assert "### The calibration file" in text and "`board_id`" in text, page


def test_a_leg_device_that_does_not_exist_is_refused_before_the_autopilot() -> None:
    err = one_line(land("--connect", free_udp(), "--legs-port", "/dev/no-such-legboard", "--slope", "35"))
    assert "--legs-port /dev/no-such-legboard: no such device" in err


# A board that answers exactly as the simulated one does, except that it does not say it is
# simulated: what a real leg board's HELLO_REPLY looks like.
SIMBOARD = b"SIMBOARD".hex()
REAL_BOARD = textwrap.dedent(
    """
    import sys
    from slopelander_sitl.legboard.server import BoardServer
    from slopelander.legs.messages import Capability
    server = BoardServer(link=sys.argv[1])
    server.capabilities = Capability.ANGLE_STOP
    server.open()
    print("ready", flush=True)
    try:
        server.serve_forever()
    finally:
        server.close()
    """
)


@pytest.fixture
def real_board(tmp_path: Path):
    link = tmp_path / "legs"
    proc = subprocess.Popen(
        [sys.executable, "-c", REAL_BOARD, str(link)], env=ENV, stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout.readline().strip() == "ready"
        yield link
    finally:
        proc.terminate()
        proc.wait(10)


def test_a_real_leg_board_without_a_measured_calibration_is_refused_before_the_autopilot(
    real_board: Path, tmp_path: Path
) -> None:
    err = one_line(land("--connect", free_udp(), "--legs-port", str(real_board), "--slope", "35"))
    assert "a real leg board flies only with a measured calibration (no --calibration given)" in err
    # the shipped curve passed by name is still the assumed one
    from slopelander.legs.calibration import default_calibration_path

    err = one_line(
        land(
            "--connect",
            free_udp(),
            "--legs-port",
            str(real_board),
            "--slope",
            "35",
            "--calibration",
            str(default_calibration_path()),
        )
    )
    assert "is assumed" in err


def test_a_real_leg_board_with_a_measured_calibration_goes_on_to_the_autopilot(
    real_board: Path, tmp_path: Path
) -> None:
    from slopelander.legs.calibration import default_calibration_path

    measured = tmp_path / "measured.yaml"
    text = default_calibration_path().read_text()
    assert "provenance: assumed" in text
    # measured on this board: the id its HELLO_REPLY gives ("SIMBOARD")
    measured.write_text(text.replace("provenance: assumed", f"provenance: measured\nboard_id: {SIMBOARD}"))
    wait = tmp_path / "wait.yaml"
    wait.write_text("link:\n  heartbeat_wait_s: 1\n")  # no autopilot here: the check is that it got this far
    flight = ["--connect", free_udp(), "--legs-port", str(real_board), "--slope", "35"]
    out = land(*flight, "--calibration", str(measured), "--config", str(wait))
    assert out.returncode == 1 and "no autopilot heartbeat within 1 s" in out.stderr, out.stderr


@pytest.mark.parametrize("check", [False, True])
def test_a_measured_calibration_that_names_no_board_is_refused_on_a_real_board(
    real_board: Path, tmp_path: Path, check: bool
) -> None:
    """A measured file that does not say which board it was measured on cannot be checked against
    the one plugged in: refused before the autopilot, as ``legs status`` refuses it."""
    from slopelander.legs.calibration import default_calibration_path

    anonymous = tmp_path / "anonymous.yaml"
    anonymous.write_text(
        default_calibration_path().read_text().replace("provenance: assumed", "provenance: measured")
    )
    how = ["--check"] if check else ["--slope", "35"]
    err = one_line(
        land("--connect", free_udp(), "--legs-port", str(real_board), *how, "--calibration", str(anonymous))
    )
    assert f"{anonymous} names no board_id: it cannot be checked against this board" in err


@pytest.mark.slow
def test_state_changes_print_as_they_happen_and_the_landing_leaves_its_folder(tmp_path: Path) -> None:
    import json

    from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle

    board = start_legboard(clock="external")
    vehicle = start_vehicle(scenario={"slope_deg": 35.0}, legboard_control=board.control)
    try:
        t0 = time.monotonic()
        args = ["--connect", vehicle.mavlink_url, "--legs-port", board.pty, "--slope", "35", "--timeout", "6"]
        proc = subprocess.Popen(
            [sys.executable, "-m", "slopelander.cli", "land", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=ENV,
            cwd=tmp_path,
        )
        arrivals: list[tuple[float, str]] = []
        for line in proc.stdout:
            arrivals.append((time.monotonic() - t0, line.rstrip()))
        proc.wait(60)
        ended = time.monotonic() - t0
    finally:
        vehicle.stop()
        board.stop()
    lines = [text for _, text in arrivals]
    assert any("(simulated leg board: torques through the ASSUMED calibration" in t for t in lines), lines
    first = next(t for t, text in arrivals if "-> PRESET" in text)
    aborted = next(t for t, text in arrivals if "-> ABORTED" in text and "not finished within 6 s" in text)
    assert ended - first > 3.0, arrivals  # printed while landing, not all at the end
    assert aborted - first > 3.0, arrivals
    assert "outcome: ABORTED" in lines, lines
    # without --out, a folder named for the time in the current folder, holding the evidence
    (folder,) = tmp_path.iterdir()
    assert folder.name.startswith("landing-"), folder
    files = {p.name for p in folder.iterdir()}
    assert {
        "flight.tlog",
        "transitions.jsonl",
        "result.json",
        "slope_estimate.json",
        "flight.png",
    } <= files, files
    png = (folder / "flight.png").read_bytes()  # the pilot's picture of the landing, as demo's
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000, len(png)
    assert f"picture: {folder.name}/flight.png" in lines, lines
    result = json.loads((folder / "result.json").read_text())
    assert result["outcome"] == "ABORTED" and result["transitions"][-1]["to"] == "ABORTED"
    from pymavlink import mavutil

    log = mavutil.mavlink_connection(str(folder / "flight.tlog"))
    kinds = set()
    while (msg := log.recv_match()) is not None:
        kinds.add(msg.get_type())
    assert {"HEARTBEAT", "RAW_IMU", "DISTANCE_SENSOR", "SERVO_OUTPUT_RAW"} <= kinds, kinds


@pytest.mark.slow
def test_the_transitions_file_holds_the_transitions_printed(tmp_path: Path) -> None:
    import json

    from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle

    board = start_legboard(clock="external")
    vehicle = start_vehicle(scenario={"slope_deg": 35.0}, legboard_control=board.control)
    folder = tmp_path / "landing"
    try:
        out = land(
            "--connect",
            vehicle.mavlink_url,
            "--legs-port",
            board.pty,
            "--slope",
            "35",
            "--timeout",
            "3",
            "--out",
            str(folder),
        )
        check = land("--connect", vehicle.mavlink_url, "--legs-port", board.pty, "--check")
    finally:
        vehicle.stop()
        board.stop()
    assert out.returncode == 3, out.stderr
    lines = [json.loads(x) for x in (folder / "transitions.jsonl").read_text().splitlines()]
    # first the slope the companion measured (docs/slope-estimate.md), then the transitions
    assert "slope_estimate" in lines[0] and lines[0]["slope_deg"] == 35.0, lines[0]
    entries = lines[1:]
    assert [e["to"] for e in entries][:2] == ["PRESET", "LEGS_WAIT"] and entries[-1]["to"] == "ABORTED"
    printed = [x for x in out.stdout.splitlines() if " -> " in x]
    assert len(printed) == len(entries)
    assert all(e["to"] in p and e["reason"] in p for e, p in zip(entries, printed, strict=True))
    assert f"transitions: {folder / 'transitions.jsonl'}" in out.stdout
    # --check: the board and the autopilot asked what they are, nothing flown, nothing written
    assert check.returncode == 0, check.stdout + check.stderr
    assert "protocol" in check.stdout and "on-board script v" in check.stdout
    assert "mode STABILIZE, disarmed" in check.stdout and check.stdout.rstrip().endswith("ready to fly")
    assert "-> PRESET" not in check.stdout


@contextmanager
def simulated(**vehicle_kw: object) -> Iterator[tuple[str, str, Path]]:
    """A simulated vehicle and a leg board on the wall clock (--check flies nothing): its MAVLink
    URL, the board's pty and its control socket."""
    from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle

    board = start_legboard()
    try:
        vehicle = start_vehicle(scenario={"slope_deg": 35.0}, **vehicle_kw)
        try:
            yield vehicle.mavlink_url, board.pty, board.control
        finally:
            vehicle.stop()
    finally:
        board.stop()


def not_ready(out: subprocess.CompletedProcess[str]) -> list[str]:
    """The reasons ``--check`` gives, having said it is not ready (exit 1)."""
    assert out.returncode == 1, out.stdout + out.stderr
    lines = out.stdout.splitlines()
    reasons = [x.removeprefix("not ready: ") for x in lines if x.startswith("not ready: ")]
    assert lines[-1] == f"{len(reasons)} problem(s): not ready to fly", out.stdout
    return reasons


@pytest.mark.slow
def test_check_refuses_a_calibration_that_cannot_take_the_tables_torques(tmp_path: Path) -> None:
    """A curve that reaches only 1.6 N·m cannot set the table's stronger presets: ``land --check``
    says so, as ``legs status --calibration`` does, instead of "ready to fly"."""
    import yaml

    from slopelander.legs.calibration import default_calibration_path

    weak = tmp_path / "weak.yaml"
    doc = yaml.safe_load(default_calibration_path().read_text())
    for entry in doc["legs"]:
        entry["torque_nm"] = [round(t / 2, 4) for t in entry["torque_nm"]]  # up to 1.6 N·m
    weak.write_text(yaml.safe_dump(doc))
    with simulated() as (url, pty, _):
        out = land("--connect", url, "--legs-port", pty, "--check", "--calibration", str(weak))
    reasons = not_ready(out)
    assert any(r.startswith("leg 1 cannot take the table's tau_down of") for r in reasons), reasons
    assert all("script" not in r for r in reasons), reasons  # the rest of the vehicle is ready


@pytest.mark.slow
def test_check_names_a_silent_on_board_script() -> None:
    with simulated(no_script=True) as (url, pty, _):
        out = land("--connect", url, "--legs-port", pty, "--check")
    assert not_ready(out) == [
        "the on-board script is silent (no SL_VER): load it (firmware_params/README.md)"
    ]


@pytest.mark.slow
def test_check_names_an_on_board_script_of_another_version(tmp_path: Path) -> None:
    from slopelander.controller.states.base import SCRIPT_CONTRACT

    shipped = (ROOT / "firmware_params" / "scripts" / "slopelander.lua").read_text()
    older = tmp_path / "slopelander.lua"
    line = f"local VERSION = {SCRIPT_CONTRACT} "
    assert shipped.count(line) == 1
    older.write_text(shipped.replace(line, f"local VERSION = {SCRIPT_CONTRACT - 1} "))
    with simulated(script=older) as (url, pty, _):
        out = land("--connect", url, "--legs-port", pty, "--check")
    assert not_ready(out) == [
        f"on-board script v{SCRIPT_CONTRACT - 1}, this companion needs v{SCRIPT_CONTRACT}"
    ]


@pytest.mark.slow
def test_check_names_a_faulted_leg() -> None:
    """A leg whose motor tripped its over-current protection stays faulted until loosened after
    the repair: ``--check`` names it and the fault."""
    from slopelander.legs.driver import LegBoard
    from slopelander_sitl.legboard.control import BoardControl

    with simulated() as (url, pty, control):
        with BoardControl(control) as ctl:
            ctl.inject("overcurrent", leg=1)
        with LegBoard.open(pty, timeout=5.0) as legs:
            legs.start_currents({1: 100})
            deadline = time.monotonic() + 10.0
            while not legs.query().faults and time.monotonic() < deadline:
                time.sleep(0.05)
        out = land("--connect", url, "--legs-port", pty, "--check")
    reasons = not_ready(out)
    assert reasons == [
        "leg 1 faulted: over-current: motor current above the limit, motor switched off "
        "(loosen it after the repair)"
    ], reasons


def test_a_refused_mode_is_named_once() -> None:
    """CHECKS reads the mode from the vehicle's HEARTBEAT: STABILIZE (0) is a name, not "mode 0"."""
    from slopelander.controller.config import load_config
    from slopelander.controller.link import Link
    from slopelander.controller.runner import Lander
    from slopelander.controller.states.checks import refusal
    from slopelander_sitl.vehicle.launch import start_vehicle

    vehicle = start_vehicle(scenario={"slope_deg": 35.0})
    try:
        link = Link(vehicle.mavlink_url)
        try:
            link.wait_autopilot(timeout_s=20)
            assert link.last["HEARTBEAT"].custom_mode == 0  # it starts in STABILIZE
            inp = Lander(link, load_config(None), (1.0, 1.0)).inputs()
        finally:
            link.close()
    finally:
        vehicle.stop()
    from slopelander.controller.states.base import SCRIPT_CONTRACT

    ready = dataclasses.replace(
        inp, script_present=True, script_version=SCRIPT_CONTRACT, legs_ready=True, range_m=2.0, range_ok=True
    )
    ready = dataclasses.replace(ready, speed_mps=0.0)
    assert refusal(ready) == "mode STABILIZE, GUIDED needed"
