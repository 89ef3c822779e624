"""``python -m slopelander_sitl.ardupilot``: one ArduCopter SITL and its JSON physics, run inside a
loopback-only network namespace (started by :func:`slopelander_sitl.ardupilot.launch.start_arducopter`
through ``unshare``; refuses to run anywhere else).

In its folder (``--dir``): ArduCopter's working directory (``eeprom.bin``, ``logs/``,
``scripts/slopelander.lua``), ``arducopter.log`` (its console), ``statustext.log`` (every
STATUSTEXT it sent on SERIAL0, with its boot time), ``events.jsonl`` (the physics' measurement
events) and two UNIX sockets joined to its MAVLink ports: ``serial1.sock`` to TCP 5762 (SERIAL1:
the companion's link) and ``serial2.sock`` to TCP 5763 (SERIAL2: a ground station).
SERIAL0 (TCP 5760), which ArduCopter waits for before it boots, is held by this process.

With ``--boot-speedup N``, ArduCopter boots at N times real time and is set to ``--speedup``
before this process says it is ready (``slopelander_sitl.ardupilot.fast_boot`` has the rules).

The companion's TIMESYNC echoes on SERIAL1 are read on their way in (``slopelander_sitl.ardupilot.echo_tap``)
and the physics holds ArduCopter while the companion is behind, and keeps it to real time within
1.6 m of the ground while the on-board script may be timing something
(``slopelander_sitl.json_physics.companion_gate``), unless ``--no-companion-lockstep``.
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

from slopelander_sitl.ardupilot.fast_boot import FastBoot
from slopelander_sitl.netns import NamespaceError, bring_loopback_up
from slopelander_sitl.parent_watch import watch_parent
from slopelander_sitl.vehicle.launch import REPO

SCRIPT = REPO / "firmware_params" / "scripts" / "slopelander.lua"
PARAMS = REPO / "firmware_params" / "sitl-json.parm"
#: where ArduCopter boots: the position only matters to its EKF and its magnetic model
HOME = "47.3977,8.5456,400,0"
#: SITL's MAVLink TCP ports with ``-I0``: SERIAL0, SERIAL1, SERIAL2
CONSOLE_PORT, COMPANION_PORT, GCS_PORT = 5760, 5762, 5763
JSON_PORT = 9002
#: the physics' gate, where the companion's echoes go (slopelander_sitl.json_physics.companion_gate)
GATE_PORT = 9102
#: below this height over the surface the physics keeps ArduCopter to real time while the script
#: may be timing something (src/slopelander_sitl/json_physics/companion_gate.py says why): just above the
#: height
#: the shipped settings arm the reflex at (``reflex.arm_height_m``, 1.5 m); nothing the script does
#: is timed before it is armed. A landing armed higher runs its first metres above real time.
REAL_TIME_BELOW_M = 1.6
#: SITL's RC input with ``-I0`` (``SIM::rcin_port``): the scenario's sticks and switches go there
RC_PORT = 5501
_PR_SET_PDEATHSIG = 1


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m slopelander_sitl.ardupilot", description=__doc__)
    ap.add_argument("--dir", type=Path, required=True, help="working folder (created if missing)")
    ap.add_argument("--binary", type=Path, required=True, help="the arducopter SITL binary")
    ap.add_argument("--scenario", type=Path, default=None, help="scenario YAML of the physics")
    ap.add_argument("--legs", type=Path, default=None, help="the simulated leg board's control socket")
    ap.add_argument("--speedup", type=float, default=1.0, help="ArduCopter's --speedup")
    ap.add_argument(
        "--boot-speedup",
        type=float,
        default=None,
        help="ArduCopter's speed-up until it could arm (then --speedup)",
    )
    ap.add_argument("--params", type=Path, action="append", default=[], help="extra .parm files")
    ap.add_argument("--no-script", action="store_true", help="boot without the on-board script")
    ap.add_argument(
        "--no-companion-lockstep",
        action="store_true",
        help="let ArduCopter run ahead of the companion (its echoes are not read)",
    )
    ap.add_argument(
        "--script", type=Path, default=SCRIPT, help="the Lua script to run (default: slopelander's)"
    )
    return ap.parse_args(argv)


def _die_with_parent() -> None:
    """In ArduCopter's child before exec: it gets SIGKILL when this process ends, however it ends."""
    ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)


class Console:
    """Holds SERIAL0 (ArduCopter boots once it is connected), logs its STATUSTEXTs, tells when
    the first HEARTBEAT came and, with a :class:`FastBoot`, sets the parameters it asks for
    until it is done (:attr:`ready`)."""

    def __init__(self, folder: Path, boot: FastBoot | None = None) -> None:
        from pymavlink import mavutil

        from slopelander_sitl.bridge import connect_retrying

        self.conn = connect_retrying(
            lambda: mavutil.mavlink_connection(f"tcp:127.0.0.1:{CONSOLE_PORT}", source_system=254), 30.0
        )
        self.heartbeat = threading.Event()
        self.boot = boot
        self.ready = threading.Event()
        if boot is None:
            self.ready.set()
        self.running = True
        self.log = open(folder / "statustext.log", "a", buffering=1)  # noqa: SIM115 - closed in stop()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        from pymavlink import mavutil

        boot_ms, beat, asked, status_asked, set_asked = 0, 0.0, 0.0, 0.0, 0.0
        seen: set[str] = set()
        boot = self.boot
        while self.running:
            # ArduPilot sends STATUSTEXT only on channels it has heard a MAVLink message on
            # (GCS_MAVLINK::active_channel_mask): say hello as a ground station does, at 1 Hz
            now = time.monotonic()
            if not boot_ms and now - asked >= 0.2:
                # SYSTEM_TIME at 10 Hz: the boot time written beside each STATUSTEXT. Asked until
                # it comes: ArduCopter, still booting, lets the first requests go unanswered
                self.conn.mav.command_long_send(1, 1, 511, 0, 2, 100_000, 0, 0, 0, 0, 0)
                asked = now
            if boot is not None and not boot.done:
                if boot_ms and not {"SYS_STATUS", "EKF_STATUS_REPORT"} <= seen and now - status_asked >= 1.0:
                    # SYS_STATUS and EKF_STATUS_REPORT at 5 Hz, asked until they come
                    for msg_id in (1, 193):
                        self.conn.mav.command_long_send(1, 1, 511, 0, msg_id, 200_000, 0, 0, 0, 0, 0)
                    status_asked = now
                want = boot.pending
                if want is not None and now - set_asked >= 0.5:
                    name, value = want
                    self.conn.mav.param_set_send(
                        1, 1, name.encode(), value, mavutil.mavlink.MAV_PARAM_TYPE_REAL32
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
            seen.add(kind)
            if kind == "HEARTBEAT":
                self.heartbeat.set()
            elif kind == "SYSTEM_TIME":
                boot_ms = m.time_boot_ms
            elif kind == "STATUSTEXT":
                self.log.write(f"{boot_ms / 1000:.3f} {m.severity} {m.text}\n")
            if boot is not None and not boot.done:
                boot.heard(kind, m)
                if boot.done:
                    self.ready.set()

    def stop(self) -> None:
        self.running = False
        self.thread.join(2.0)
        self.conn.close()
        self.log.close()


def warm() -> None:
    """What a pod loads before ArduCopter boots, loaded once in the process pods are forked from
    (:mod:`slopelander_sitl.warm`)."""
    import pymavlink.mavutil  # noqa: F401

    import slopelander_sitl.ardupilot.echo_tap
    import slopelander_sitl.bridge
    import slopelander_sitl.json_physics.launch  # noqa: F401


def main(argv: list[str] | None = None) -> int:
    a = parse_args(argv)

    def fail(msg: str) -> int:
        print(f"slopelander_sitl.ardupilot: error: {msg}", file=sys.stderr, flush=True)
        return 2

    try:
        bring_loopback_up()
    except NamespaceError as exc:
        return fail(str(exc))
    from slopelander_sitl.ardupilot.echo_tap import EchoTap
    from slopelander_sitl.bridge import unix_to_tcp
    from slopelander_sitl.json_physics.launch import start_json_physics

    folder = a.dir
    folder.mkdir(parents=True, exist_ok=True)
    if not a.no_script:
        (folder / "scripts").mkdir(exist_ok=True)
        shutil.copy(a.script, folder / "scripts" / a.script.name)
    scenario = yaml.safe_load(a.scenario.read_text()) if a.scenario else None
    gate = None if a.no_companion_lockstep else GATE_PORT
    try:
        physics = start_json_physics(
            scenario=scenario,
            legs=a.legs,
            port=JSON_PORT,
            events=folder / "events.jsonl",
            rc_port=RC_PORT,
            lockstep_port=gate,
            real_time_below_m=None if gate is None else REAL_TIME_BELOW_M,
        )
    except RuntimeError as exc:
        return fail(str(exc))
    boot = FastBoot(a.speedup) if a.boot_speedup is not None else None
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
            unix_to_tcp(
                str(folder / "serial1.sock"),
                COMPANION_PORT,
                "serial1",
                tap=None if gate is None else (lambda: EchoTap(gate)),
            ),
            unix_to_tcp(str(folder / "serial2.sock"), GCS_PORT, "serial2"),
        ]
        try:
            console = Console(folder, boot)
        except OSError as exc:
            return fail(f"ArduCopter's SERIAL0 (tcp {CONSOLE_PORT}) did not open: {exc}")
        while not (console.heartbeat.is_set() and console.ready.is_set()):
            time.sleep(0.05)
            if ap.poll() is not None:
                return fail(f"arducopter exited with status {ap.returncode} before it was ready")
            if stopping.is_set():
                return 0
        said = ""
        if boot is not None:
            said = f" boot={boot.done_at:.1f}s ({boot.why}; now at speed-up {a.speedup:g})"
        print(f"arducopter ready folder={folder} pid={ap.pid}{said}", flush=True)
        while not stopping.wait(0.2):
            if ap.poll() is not None:
                print(
                    f"slopelander_sitl.ardupilot: arducopter exited with status {ap.returncode}",
                    file=sys.stderr,
                )
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
