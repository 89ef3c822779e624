"""``python -m sitl.ardupilot``: one ArduCopter SITL and its JSON physics, run inside a
loopback-only network namespace (started by :func:`sitl.ardupilot.launch.start_arducopter`
through ``unshare``; refuses to run anywhere else).

In its folder (``--dir``): ArduCopter's working directory (``eeprom.bin``, ``logs/``,
``scripts/slopelander.lua``), ``arducopter.log`` (its console), ``statustext.log`` (every
STATUSTEXT it sent on SERIAL0, with its boot time), ``events.jsonl`` (the physics' measurement
events) and two UNIX sockets joined to its MAVLink ports: ``serial1.sock`` to TCP 5762 (SERIAL1:
the companion's link) and ``serial2.sock`` to TCP 5763 (SERIAL2: a ground station).
SERIAL0 (TCP 5760), which ArduCopter waits for before it boots, is held by this process.

With ``--boot-speedup N``, ArduCopter boots at N times real time (in lock-step with the physics,
so in practice as fast as the two can step) until it could arm in GUIDED, and is then set back to
``--speedup`` before this process says it is ready: MAVProxy's ``sitl_autospeedup`` module does
the same for a freshly booted SITL vehicle. The start-up (EKF alignment, GPS, origin, the EKF
using GPS) is about 40 s of vehicle time that nobody needs to wait for in real time; the flight
after it runs at the speed asked for. "Could arm" is read from two messages: SYS_STATUS's pre-arm
bit, and EKF_STATUS_REPORT's horizontal position, without which GUIDED refuses to arm ("Need
Position Estimate": ``Copter::ekf_has_absolute_position``, ArduCopter/system.cpp, which takes
the absolute or the predicted absolute position while disarmed). A vehicle whose pre-arm checks
still fail at ``BOOT_CAP_S`` of boot time (one leaning on a roof, armed with the force flag)
is set back once it has the position, and one without a position at ``BOOT_GIVE_UP_S``.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import yaml

from sitl.netns import NamespaceError, bring_loopback_up
from sitl.parent_watch import watch_parent
from sitl.vehicle.launch import REPO

SCRIPT = REPO / "firmware_params" / "scripts" / "slopelander.lua"
PARAMS = REPO / "firmware_params" / "sitl-json.parm"
#: where ArduCopter boots: the position only matters to its EKF and its magnetic model
HOME = "47.3977,8.5456,400,0"
#: SITL's MAVLink TCP ports with ``-I0``: SERIAL0, SERIAL1, SERIAL2
CONSOLE_PORT, COMPANION_PORT, GCS_PORT = 5760, 5762, 5763
JSON_PORT = 9002
#: SITL's RC input with ``-I0`` (``SIM::rcin_port``): the scenario's sticks and switches go there
RC_PORT = 5501
_PR_SET_PDEATHSIG = 1
#: SYS_STATUS's sensor bit that ArduPilot sets while its pre-arm checks pass
#: (MAV_SYS_STATUS_PREARM_CHECK, GCS_MAVLINK::update_sensor_status_flags)
PREARM_CHECK = 0x10000000
#: EKF_STATUS_REPORT flags of an absolute horizontal position, current or predicted
#: (EKF_POS_HORIZ_ABS, EKF_PRED_POS_HORIZ_ABS)
POSITION_FLAGS = 16 | 512
#: s of boot time after which a boot speed-up ends once the EKF has a position, even if the
#: pre-arm checks still fail: on the pad they pass at 20-25 s and the position comes at 38-41 s
#: (2026-11-27); a lean on a roof never passes
BOOT_CAP_S = 45.0
#: s of boot time after which it ends in any case: the caller's own time-outs then report it
BOOT_GIVE_UP_S = 90.0


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m sitl.ardupilot", description=__doc__)
    ap.add_argument("--dir", type=Path, required=True, help="working folder (created if missing)")
    ap.add_argument("--binary", type=Path, required=True, help="the arducopter SITL binary")
    ap.add_argument("--scenario", type=Path, default=None, help="scenario YAML of the physics")
    ap.add_argument("--legs", type=Path, default=None, help="the simulated leg board's control socket")
    ap.add_argument("--speedup", type=float, default=1.0, help="ArduCopter's --speedup")
    ap.add_argument(
        "--boot-speedup",
        type=float,
        default=None,
        help="ArduCopter's speed-up until its pre-arm checks pass (then --speedup)",
    )
    ap.add_argument("--params", type=Path, action="append", default=[], help="extra .parm files")
    ap.add_argument("--no-script", action="store_true", help="boot without the on-board script")
    ap.add_argument(
        "--script", type=Path, default=SCRIPT, help="the Lua script to run (default: slopelander's)"
    )
    return ap.parse_args(argv)


def _die_with_parent() -> None:
    """In ArduCopter's child before exec: it gets SIGKILL when this process ends, however it ends."""
    ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)


class Console:
    """Holds SERIAL0 (ArduCopter boots once it is connected), logs its STATUSTEXTs, tells when
    the first HEARTBEAT came and, with ``flight_speedup``, sets ``SIM_SPEEDUP`` to it once the
    pre-arm checks pass (or at ``BOOT_CAP_S``) and then tells :attr:`at_flight_speed`."""

    def __init__(self, folder: Path, flight_speedup: float | None = None) -> None:
        from pymavlink import mavutil

        from sitl.bridge import connect_retrying

        self.conn = connect_retrying(
            lambda: mavutil.mavlink_connection(f"tcp:127.0.0.1:{CONSOLE_PORT}", source_system=254), 30.0
        )
        self.heartbeat = threading.Event()
        self.flight_speedup = flight_speedup
        self.at_flight_speed = threading.Event()
        #: (boot s, why) when the speed-up ended
        self.speed_dropped: tuple[float, str] | None = None
        if flight_speedup is None:
            self.at_flight_speed.set()
        self.running = True
        self.log = open(folder / "statustext.log", "a", buffering=1)  # noqa: SIM115 - closed in stop()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        from pymavlink import mavutil

        boot_ms, beat, asked, status_asked, set_asked = 0, 0.0, 0.0, 0.0, 0.0
        drop_why, status_seen, ekf_seen = None, False, False
        prearm_ok = position_ok = False
        while self.running:
            # ArduPilot sends STATUSTEXT only on channels it has heard a MAVLink message on
            # (GCS_MAVLINK::active_channel_mask): say hello as a ground station does, at 1 Hz
            now = time.monotonic()
            if not boot_ms and now - asked >= 0.2:
                # SYSTEM_TIME at 10 Hz: the boot time written beside each STATUSTEXT. Asked until
                # it comes: ArduCopter, still booting, lets the first requests go unanswered
                self.conn.mav.command_long_send(1, 1, 511, 0, 2, 100_000, 0, 0, 0, 0, 0)
                asked = now
            if not self.at_flight_speed.is_set():
                if boot_ms and not (status_seen and ekf_seen) and now - status_asked >= 1.0:
                    # SYS_STATUS and EKF_STATUS_REPORT at 5 Hz, asked until they come
                    for msg_id in (1, 193):
                        self.conn.mav.command_long_send(1, 1, 511, 0, msg_id, 200_000, 0, 0, 0, 0, 0)
                    status_asked = now
                boot_s = boot_ms / 1000.0
                if drop_why is None:
                    if prearm_ok and position_ok:
                        drop_why = "pre-arm checks pass, EKF has a position"
                    elif position_ok and boot_s >= BOOT_CAP_S:
                        drop_why = f"EKF has a position, pre-arm checks still failing at {BOOT_CAP_S:g} s"
                    elif boot_s >= BOOT_GIVE_UP_S:
                        drop_why = f"no EKF position at {BOOT_GIVE_UP_S:g} s"
                if drop_why is not None and now - set_asked >= 0.5:
                    self.conn.mav.param_set_send(
                        1, 1, b"SIM_SPEEDUP", self.flight_speedup, mavutil.mavlink.MAV_PARAM_TYPE_REAL32
                    )
                    set_asked = now
            if now - beat >= 1.0:
                beat = now
                self.conn.mav.heartbeat_send(
                    mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0
                )
            try:
                m = self.conn.recv_match(blocking=True, timeout=0.5)
            except (OSError, ConnectionError):
                return
            if m is None:
                continue
            kind = m.get_type()
            if kind == "HEARTBEAT":
                self.heartbeat.set()
            elif kind == "SYSTEM_TIME":
                boot_ms = m.time_boot_ms
            elif kind == "SYS_STATUS":
                status_seen = True
                prearm_ok = bool(m.onboard_control_sensors_health & PREARM_CHECK)
            elif kind == "EKF_STATUS_REPORT":
                ekf_seen = True
                position_ok = bool(m.flags & POSITION_FLAGS)
            elif (
                kind == "PARAM_VALUE"
                and drop_why is not None
                and not self.at_flight_speed.is_set()
                and m.param_id == "SIM_SPEEDUP"
                and abs(m.param_value - self.flight_speedup) < 1e-3
            ):
                self.speed_dropped = (boot_ms / 1000.0, drop_why)
                self.at_flight_speed.set()
            elif kind == "STATUSTEXT":
                self.log.write(f"{boot_ms / 1000:.3f} {m.severity} {m.text}\n")

    def stop(self) -> None:
        self.running = False
        self.thread.join(2.0)
        self.conn.close()
        self.log.close()


def main(argv: list[str] | None = None) -> int:
    a = parse_args(argv)

    def fail(msg: str) -> int:
        print(f"sitl.ardupilot: error: {msg}", file=sys.stderr, flush=True)
        return 2

    try:
        bring_loopback_up()
    except NamespaceError as exc:
        return fail(str(exc))
    from sitl.bridge import unix_to_tcp
    from sitl.json_physics.launch import start_json_physics

    folder = a.dir
    folder.mkdir(parents=True, exist_ok=True)
    if not a.no_script:
        (folder / "scripts").mkdir(exist_ok=True)
        shutil.copy(a.script, folder / "scripts" / a.script.name)
    scenario = yaml.safe_load(a.scenario.read_text()) if a.scenario else None
    try:
        physics = start_json_physics(
            scenario=scenario, legs=a.legs, port=JSON_PORT, events=folder / "events.jsonl", rc_port=RC_PORT
        )
    except RuntimeError as exc:
        return fail(str(exc))
    defaults = ",".join(str(p) for p in [PARAMS, *a.params])
    with open(folder / "arducopter.log", "w") as log:
        ap = subprocess.Popen(
            [
                str(a.binary),
                "--model",
                "JSON:127.0.0.1",
                "--speedup",
                f"{a.speedup if a.boot_speedup is None else a.boot_speedup:g}",
                "-I0",
                "--defaults",
                defaults,
                "--home",
                HOME,
            ],
            cwd=folder,
            stdout=log,
            stderr=subprocess.STDOUT,
            preexec_fn=_die_with_parent,
        )
    bridges = []
    console = None
    stopping = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stopping.set())
    signal.signal(signal.SIGINT, lambda *_: stopping.set())
    watch_parent()
    try:
        bridges = [
            unix_to_tcp(str(folder / "serial1.sock"), COMPANION_PORT, "serial1"),
            unix_to_tcp(str(folder / "serial2.sock"), GCS_PORT, "serial2"),
        ]
        try:
            console = Console(folder, None if a.boot_speedup is None else a.speedup)
        except OSError as exc:
            return fail(f"ArduCopter's SERIAL0 (tcp {CONSOLE_PORT}) did not open: {exc}")
        while not (console.heartbeat.is_set() and console.at_flight_speed.is_set()):
            time.sleep(0.05)
            if ap.poll() is not None:
                return fail(f"arducopter exited with status {ap.returncode} before it was ready")
            if stopping.is_set():
                return 0
        boot = ""
        if console.speed_dropped is not None:
            at, why = console.speed_dropped
            boot = f" boot={at:.1f}s ({why}; now at speed-up {a.speedup:g})"
        print(f"arducopter ready folder={folder} pid={ap.pid}{boot}", flush=True)
        while not stopping.wait(0.2):
            if ap.poll() is not None:
                print(f"sitl.ardupilot: arducopter exited with status {ap.returncode}", file=sys.stderr)
                return 1
        return 0
    finally:
        for b in bridges:
            b.close()
        if console is not None:
            console.stop()
        if ap.poll() is None:
            ap.terminate()
            try:
                ap.wait(5)
            except subprocess.TimeoutExpired:
                ap.kill()
                ap.wait()
        physics.stop()
        with contextlib.suppress(OSError):
            (folder / "physics-summary.txt").write_text(physics.summary + "\n" + physics.stderr())
        print(f"arducopter stopped status={ap.returncode} {physics.summary}", flush=True)
