"""Soak: many simulated landings across the envelope with random faults, by the companion's
controller against the simulated vehicle and leg board (real processes, lock-step, the link
through the fault-injecting relay). Prints the outcome table, the safety checks and the growth of
the companion process (this one: it runs the controller) in memory, threads and open files. With
glibc, memory is also split into the C heap's bytes in use and the freed bytes the allocator keeps
(``heap_used_mb``, ``heap_kept_free_mb``): resident memory can grow by the second alone.

    python3 benchmarks/soak.py [--landings 1000] [--seed 1] [--per-vehicle 25] [--speed 8]
                               [--minutes M] [--log soak.jsonl [--resume]]
    python3 benchmarks/soak.py --autopilot ardupilot --landings 200 --log run.jsonl [--resume]

Envelope: each vehicle (started afresh every ``--per-vehicle`` landings, and after a landing that
leaves it unusable: an emergency stop, an unplugged leg board, a rig error) flies one roof of
``--slopes`` (15..45 deg; 0..55 on ArduCopter); each landing draws an impact speed of 1.0..2.5
m/s (the cut height is chosen for it) and flies the lookup table's preset for that cell (its
torques and uphill angle, as ``slopelander land`` sets them).

``--autopilot ardupilot`` flies real ArduCopter SITL (``SLOPELANDER_ARDUCOPTER`` or
``--arducopter``, in its loopback-only network namespace: ``src/slopelander_sitl/ardupilot/``) behind the same
physics, scenario, leg board and relay, with the same checks. Its script is the shipped one with
one line added at the top of its update, inert until the fault below sets ``SCR_USER1``. A vehicle
that ends a landing on the roof is started afresh (no take-off from a roof of up to 55 deg); one
that ended it in the air flies the next.

Resumable: each landing's draws come from ``(--seed, landing number)``, each vehicle's roof and
background from ``(--seed, its first landing)``; the log is appended to, one JSON line per landing
(its first line the run's settings), and ``--resume`` flies the landings the log does not hold yet
(on a fresh vehicle). A run that is not resumed refuses a log that exists.

Faults, one drawn per landing (weights in ``FAULTS``):
- ``link_noise``: for the whole landing the relay drops, duplicates, reorders, corrupts and delays
  frames (each rate drawn up to 10 %, delay up to 50 ms with jitter);
- ``cut_0.5``, ``cut_3``, ``cut_forever``: the relay cuts the link for 0.5 s, 3 s, or until the
  landing is given up (8 s of wall time, then restored to look at the vehicle), when the landing
  reaches a state drawn from PRESET .. RESET (a state the machine passes within one step is hit on
  the first poll after it: the state actually hit is what the table shows);
- ``leg_stuck``/``leg_slip``/``leg_overcurrent`` (one leg), ``leg_silent``, ``leg_corrupt`` (a byte
  rate of 1..30 %), ``leg_unplug``: injected in the board process in a drawn state;
- ``pilot_mode``: the pilot switches to LOITER in a drawn state; ``pilot_estop``: the pilot's
  emergency stop (``MAV_CMD_DO_AUX_FUNCTION`` 31) in a drawn state;
- ArduCopter only: ``companion_kill``: the companion runs as a process of its own
  (``benchmarks/soak_companion.py``: the landing session on the relay's port and the board's pty)
  and is killed (SIGKILL) when its landing reaches a drawn state of ARMED .. REVERSE; the soak
  watches on the autopilot's second MAVLink port for ``KILLED_WATCH_S`` of vehicle time, then
  starts the vehicle afresh. ``script_error``: ``SCR_USER1`` set to 1 in a drawn state, and the
  script's next update raises (its pcall: FAULT or FAULT_HELD); then the vehicle is started afresh
  (a script fault lasts until a reboot);
- in the background of every vehicle, from its scenario: rangefinder dropouts, spikes and stuck
  readings, IMU spikes and random gusts at random vehicle times; a landing that overlaps one
  lists it in the table under ``sensor faults seen``.

Checks per landing ("unsafe" = any of these):
- ``hang``: no ending (LANDED→READY, ABORTED, ESTOP, READY; FAULT_LANDED: LANDED with the
  take-off refused for a script fault, the vehicle disarmed; or HELD: :data:`slopelander_sitl.rig.HELD_S`
  of a hold in SETTLED after a slide, which waits for the pilot) within 150 s of vehicle time or
  300 s of wall time;
- ``stop_high``: the outputs stopped (vehicle event EV_STOP) before the landing's first contact
  while the body's range height was more than the cut height + 0.25 m, except after the pilot's
  emergency stop. A stop after a contact (a vehicle that flipped and tumbles down the roof, whose
  clearance the check cannot read) is listed in the row as ``stops_after_contact``, not as unsafe;
- ``reverse_in_air``: reverse thrust (EV_RVT) with no contact in the 2 s before it and the body
  more than 0.3 m above the roof;
- ``armed_stopped_in_air``/``disarmed_in_air``: at the end, more than 0.3 m above the roof, armed
  with all four outputs in the stop band, or disarmed (except after an emergency stop);
- ``contact_under_power``: the landing's first contact (EV_CONTACT) with no stop of the outputs
  (EV_STOP) before it in the landing;
- ``armed_on_roof_unheld``: at the end, within 0.3 m of the roof, armed, and not all four outputs
  in the stop band (nobody holds the motors stopped: the autopilot's mixer drives them);
- ``legs_loose_on_ground``: LANDED with a leg LOOSE, or the legs loosened (RESET entered) with the
  body's range height under ``takeoff.clear_height_m`` − 0.1 m.
Heights over the roof are the vehicle's (LOCAL_POSITION_NED, counted from home, 0.15 m above its
pad) less the roof's height below it; on ArduCopter, whose LOCAL_POSITION_NED is its EKF's
estimate, the physics' true height (``TR_H``) counted the same way. The checks against a range
threshold (the cut, the clear height) add the height of home over the pad
(``Rig.home_range_m``, 0.15 m): the *range height*, the rangefinder's reading were the body level.
An earlier version did not, and flagged legs loosened at a range height of 0.76-0.84 m as
loosened at 0.61-0.69 m.
Telemetry lost in a cut is not seen; the end state after the link is back is.
"""

from __future__ import annotations

import argparse
import bisect
import ctypes
import gc
import io
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from datetime import date
from itertools import pairwise
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from slopelander.controller.landing import leg_geometry  # noqa: E402
from slopelander.controller.link import mavlink  # noqa: E402
from slopelander.controller.session import STREAMS, Session  # noqa: E402
from slopelander.controller.table import DEFAULT_TABLE, LookupTable  # noqa: E402
from slopelander_sitl.legboard.control import BoardControl  # noqa: E402
from slopelander_sitl.rig import HELD_S, RIG_RATES, TRACK_MESSAGES, Rig, RigError, add_autopilot_args, config  # noqa: E402
from slopelander_sitl.vehicle.wind import MAX_RANDOM_GUSTS as MAX_GUSTS  # noqa: E402

LOITER, GUIDED = 5, 4
MAV_CMD_DO_SET_MODE, MAV_CMD_DO_AUX_FUNCTION, AUX_MOTOR_ESTOP = 176, 218, 31
STATES = (
    "PRESET",
    "LEGS_WAIT",
    "CHECKS",
    "ARMED",
    "DESCEND",
    "CUT",
    "REVERSE",
    "SETTLED",
    "TAKEOFF",
    "RESET",
)
FAULTS = {
    "none": 10,
    "link_noise": 10,
    "cut_0.5": 8,
    "cut_3": 8,
    "cut_forever": 4,
    "leg_stuck": 3,
    "leg_slip": 3,
    "leg_overcurrent": 3,
    "leg_silent": 3,
    "leg_corrupt": 3,
    "leg_unplug": 1,
    "pilot_mode": 4,
    "pilot_estop": 1,
}
#: on ArduCopter: more of the link cuts, and the faults only it can fly (a slow landing each: the
#: weights put about half of the landings in a cut, a killed companion or a script error)
ARDUPILOT_FAULTS = {
    "none": 5,
    "link_noise": 5,
    "cut_0.5": 9,
    "cut_3": 9,
    "cut_forever": 6,
    "leg_stuck": 2,
    "leg_slip": 2,
    "leg_overcurrent": 2,
    "leg_silent": 2,
    "leg_corrupt": 2,
    "leg_unplug": 1,
    "pilot_mode": 3,
    "pilot_estop": 1,
    "companion_kill": 10,
    "script_error": 10,
}
#: the states a companion is killed in: from the reflex's arming to the reverse thrust
KILL_STATES = ("DESCEND", "ARMED", "CUT", "REVERSE")
#: vehicle seconds the soak watches the vehicle after the companion was killed
KILLED_WATCH_S = 15.0
#: the top of the script's update, where ArduCopter's copy raises on ``SCR_USER1`` 1
#: (as tests/firmware/test_script_flights.py injects its errors)
SCRIPT_UPDATE = "local function step()\n  local t = now()\n"
SCRIPT_HOOK = '  if param:get("SCR_USER1") == 1 then error("injected fault") end\n'
#: outputs in this band (us) are stopped (route A: 1500 us stopped)
STOP_BAND = (1470, 1530)
ON_ROOF_M = 0.3
#: SET_POSITION_TARGET_LOCAL_NED: a position and a yaw (velocity, acceleration, yaw rate ignored)
YAW_TARGET_MASK = 0x09F8
CONTACT_OFFSET_M = 0.06
#: the motors stop up to two 20 Hz range samples after the range crosses the cut height (the
#: script's two-sample rule): 5 cm of a 0.5 m/s descent. Without it a slow landing (1 m/s) on a
#: 48 deg roof had its cut 4 cm above the uphill foot's contact, and the foot touched 3 ms before
#: the cut (landing 79 at seed 5, 0750e6b; 12 ms after it at 23bea36)
CUT_LATENCY_M = 0.05
VEHICLE_LIMIT_S = 150.0
WALL_LIMIT_S = 300.0
FOREVER_WALL_S = 8.0


def vehicle_span_s(per_vehicle: int) -> float:
    """Vehicle seconds a vehicle's background faults and gusts are drawn over."""
    return 60.0 * per_vehicle + 200.0


def gust_count(per_vehicle: int) -> int:
    """One random gust per 20 s of the vehicle's span."""
    return max(1, int(vehicle_span_s(per_vehicle) / 20.0))


MAX_PER_VEHICLE = max(n for n in range(1, 2000) if gust_count(n) <= MAX_GUSTS)


class HangError(Exception):
    """A landing that did not end within its wall-time limit."""


class RestartVehicleError(Exception):
    """The vehicle cannot fly the next landing where it is (on a roof, on ArduCopter)."""


def faults_for(autopilot: str) -> dict[str, int]:
    return ARDUPILOT_FAULTS if autopilot == "ardupilot" else FAULTS


def hooked_script(folder: Path) -> Path:
    """The shipped on-board script with :data:`SCRIPT_HOOK` at the top of its update."""
    from slopelander_sitl.ardupilot.pod import SCRIPT

    source = SCRIPT.read_text()
    if source.count(SCRIPT_UPDATE) != 1:
        raise SystemExit(f"soak: {SCRIPT}: the script's update is no longer where the error hook goes")
    path = folder / "slopelander.lua"
    path.write_text(source.replace(SCRIPT_UPDATE, SCRIPT_UPDATE + SCRIPT_HOOK))
    return path


def watch_streams(watch: Session, wall_s: float = 30.0) -> None:
    """Ask the autopilot's second port for the session's streams and wait until they flow. Its
    COMMAND_ACKs are not waited for: on ArduCopter's SERIAL2 (MAVLink 1 unless set otherwise) the
    link matches none of them, though the streams come."""
    watch.info = watch.link.wait_autopilot(timeout_s=wall_s)
    for name, key in STREAMS:
        watch.link.request_stream(getattr(mavlink, f"MAVLINK_MSG_ID_{name}"), watch.cfg[key])
    end = time.monotonic() + wall_s
    need = ("LOCAL_POSITION_NED", "SERVO_OUTPUT_RAW", "HEARTBEAT")
    while not all(k in watch.link.last for k in need):
        if time.monotonic() > end:
            raise RigError(f"the autopilot's second port sent no {', '.join(need)} within {wall_s:g} s")
        watch.link.poll()
        time.sleep(0.005)


def stopped(servo) -> bool:
    return bool(servo) and all(STOP_BAND[0] <= v <= STOP_BAND[1] for v in servo)


def contact_range(slope_deg: float) -> float:
    g = leg_geometry()
    a = math.radians(g.leg_angle_deg)
    return g.leg_length_m * math.cos(a) + (g.joint_x_m + g.leg_length_m * math.sin(a)) * math.tan(
        math.radians(slope_deg)
    )


class _MallInfo2(ctypes.Structure):
    _fields_ = [
        ("arena", ctypes.c_size_t),
        ("ordblks", ctypes.c_size_t),
        ("smblks", ctypes.c_size_t),
        ("hblks", ctypes.c_size_t),
        ("hblkhd", ctypes.c_size_t),
        ("usmblks", ctypes.c_size_t),
        ("fsmblks", ctypes.c_size_t),
        ("uordblks", ctypes.c_size_t),
        ("fordblks", ctypes.c_size_t),
        ("keepcost", ctypes.c_size_t),
    ]


def _mallinfo():
    """glibc's ``mallinfo2`` (2.33 and later), or None where there is none."""
    try:
        fn = ctypes.CDLL("libc.so.6").mallinfo2
    except (OSError, AttributeError):
        return None
    fn.restype = _MallInfo2
    return fn


_MALLINFO = _mallinfo()


def resources() -> dict[str, float]:
    """This process's resident memory (MB), threads and open file descriptors; with glibc, also
    the C heap's bytes in use and the freed bytes it keeps (MB): resident memory that grows while
    the bytes in use do not is the allocator keeping what was freed, not a leak."""
    rss = threads = 0.0
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1]) / 1024.0
            elif line.startswith("Threads:"):
                threads = int(line.split()[1])
    out = {"rss_mb": rss, "threads": threads, "fds": len(os.listdir("/proc/self/fd"))}
    if _MALLINFO is not None:
        gc.collect()
        m = _MALLINFO()
        out["heap_used_mb"] = round((m.uordblks + m.hblkhd) / 2**20, 3)
        out["heap_kept_free_mb"] = round(m.fordblks / 2**20, 3)
    return out


def background_faults(rng: np.random.Generator, span_s: float) -> list[dict]:
    """Sensor faults at random vehicle times (about one per 40 s) for a vehicle's scenario."""
    out = []
    t = 20.0
    while True:
        t += rng.exponential(40.0)
        if t > span_s:
            return out
        kind = rng.choice(["rangefinder_dropout", "rangefinder_spike", "rangefinder_stuck", "imu_spike"])
        if kind == "rangefinder_dropout":
            f = {"end": t + rng.uniform(0.2, 3.0)}
        elif kind == "rangefinder_spike":
            f = {"end": t + rng.uniform(0.05, 0.5), "value": float(rng.uniform(0.05, 2.5))}
        elif kind == "rangefinder_stuck":
            f = {"end": t + rng.uniform(0.5, 3.0)}
        else:
            f = {"end": t + rng.uniform(0.01, 0.05), "value": float(rng.uniform(10.0, 60.0))}
        out.append({"kind": str(kind), "start": round(t, 3), **{k: round(v, 3) for k, v in f.items()}})


class Soak:
    def __init__(self, args: argparse.Namespace) -> None:
        self.a = args
        self.real = args.autopilot == "ardupilot"
        self.faults = faults_for(args.autopilot)
        if args.faults:
            self.faults = {k: v for k, v in self.faults.items() if k in args.faults}
        self.rng = np.random.default_rng(args.seed)
        self._tmp = tempfile.TemporaryDirectory(prefix="sl-soak-")
        self.script = hooked_script(Path(self._tmp.name)) if self.real else True
        self.table = LookupTable.load(DEFAULT_TABLE)
        self.rig: Rig | None = None
        self.rig_landings = 0
        self.rig_count = 0
        self.scenario_faults: list[dict] = []
        self.restarts: Counter = Counter()
        self.row: dict = {}
        self._pos_sorted: tuple | None = None  # (key, the rig's positions in time order)
        self._truth: tuple | None = None  # (key, the physics' TR_H samples in time order)

    # ---------------------------------------------------------------- vehicle life cycle
    def new_rig(self, i: int) -> None:
        """A fresh vehicle, its roof and background drawn from (seed, ``i``: its first landing)."""
        self.close_rig()
        self._pos_sorted = None
        self.rng = np.random.default_rng([self.a.seed, i, 1])
        slope = float(self.rng.uniform(*self.a.slopes))
        seed = int(self.rng.integers(1 << 30))
        span = vehicle_span_s(self.a.per_vehicle)
        self.scenario_faults = background_faults(self.rng, span)
        scenario = {
            "rc": [{"t": 0.0, "channels": {3: 1500}}],  # throttle centred: LOITER holds after an abort
            "faults": self.scenario_faults,
            "wind": {
                "random_gusts": {
                    "count": gust_count(self.a.per_vehicle),
                    "max_n": 2.0,
                    "from_s": 0.0,
                    "to_s": span,
                    "duration_s": 1.5,
                }
            },
        }
        self.rig = Rig(
            slope_deg=round(slope, 2),
            seed=seed,
            scenario=scenario,
            relay=True,
            speed=self.a.speed,
            autopilot=self.a.autopilot,
            arducopter=self.a.arducopter,
            arducopter_speedup=self.a.speedup,
            script=self.script,
        )
        self.rig_count += 1
        self.rig_landings = 0
        self.rig.take_off(3.0)

    def close_rig(self) -> None:
        if self.rig is not None:
            try:
                self.rig.close()
            finally:
                self.rig = None

    def ready_over_roof(self) -> None:
        """Bring the vehicle (whatever the last landing left) to a hover over the roof, legs loose."""
        rig = self.rig
        if self.real and rig.track.pos and self.clearance(rig.now) < ON_ROOF_M:
            raise RestartVehicleError("on the roof")
        if rig.track.pos and self.clearance(rig.now) < ON_ROOF_M:  # on the roof: from the start again
            if rig.armed():
                rig.wait_command(rig.link.command(400, 0, 21196), "disarm")  # forced, on the roof
                rig.fly_until(lambda: not rig.armed(), 5.0, "report disarmed")
            rig.take_off(3.0, force=True)
        elif not rig.armed():
            rig.take_off(3.0, force=True)
        if rig.mode() != GUIDED:
            rig.wait_command(rig.link.command(MAV_CMD_DO_SET_MODE, 1, GUIDED), "GUIDED")
            rig.fly_until(lambda: rig.mode() == GUIDED, 3.0, "report GUIDED")
        rig.go_over_roof(2.0)
        if self.real:
            self.face_downhill()
        st = rig.legs.status if rig.legs is not None else None
        # a leg a fault left latched (it may read LOOSE) refuses every preset until loosened: the
        # first soak in lock-step lost a chain of landings after each leg fault to that
        if st is None or not all(lg.state.name == "LOOSE" and not lg.fault for lg in st.legs):
            op = rig.legs.start_loosen()
            rig.fly_until(lambda: op.done, 30.0, "loosen the legs")

    def face_downhill(self, tol_deg: float = 3.0, vehicle_s: float = 20.0) -> None:
        """Turn ArduCopter to face north, down the roof's fall line (the planar model's +x), where
        it hovers. Its GUIDED yaws toward where it flies: brought back south over the roof after an
        abort it faced uphill, and the physics hands a section falling toward the vehicle's back
        over level (src/slopelander_sitl/vehicle/world.py): 9 of the first 52 contacts on 41-46 deg roofs
        were on
        a level section. The soak's landing does not turn it: its descent is vertical."""
        rig = self.rig
        _, x, z, _, _ = rig.track.pos[-1]
        info = rig.link.info
        last = [0.0]

        def send() -> None:
            if time.monotonic() - last[0] > 0.05:
                last[0] = time.monotonic()
                rig.link.conn.mav.set_position_target_local_ned_send(
                    0, info.system, info.component, mavlink.MAV_FRAME_LOCAL_NED, YAW_TARGET_MASK,
                    x, 0, -z, 0, 0, 0, 0, 0, 0, 0.0, 0,
                )  # fmt: skip

        def facing() -> bool:
            att = rig.link.last.get("ATTITUDE")
            return att is not None and abs(math.degrees(att.yaw)) < tol_deg and abs(att.yawspeed) < 0.05

        rig.fly_until(facing, vehicle_s, "face down the roof", send=send)

    def reopen_legs(self) -> None:
        rig = self.rig
        if rig.legs is not None:
            rig.legs.close()
            rig.legs = None
        with BoardControl(rig.board.control) as ctl:
            ctl.clear_faults()
            if ctl.state()["unplugged"]:
                raise RigError("leg board unplugged")
        rig.open_legs()
        # a leg the fault left latched in its fault state refuses every preset until loosened
        # ("loosen it first"), as a mechanic would do before the next flight
        if any(lg.fault for lg in (rig.legs.status.legs if rig.legs.status else ())):
            op = rig.legs.start_loosen()
            rig.fly_until(lambda: op.done, 30.0, "loosen the faulted legs")

    # --------------------------------------------------------------------- one landing
    def inject(self, fault: str, row: dict) -> None:
        rig = self.rig
        row["hit_state"] = self.lander.machine.name
        row["hit_t"] = round(rig.now, 3)
        if fault == "cut_0.5":
            rig.relay.cut(0.5)
        elif fault == "cut_3":
            rig.relay.cut(3.0)
        elif fault == "cut_forever":
            rig.relay.cut(None)
            self.forever_until = time.monotonic() + FOREVER_WALL_S
        elif fault.startswith("leg_"):
            kind = fault[4:]
            leg = int(self.rng.integers(4))
            rate = float(self.rng.uniform(0.01, 0.3))
            with BoardControl(rig.board.control) as ctl:
                if kind in ("stuck", "slip", "overcurrent"):
                    ctl.inject(kind, leg=leg)
                    row["leg"] = leg
                elif kind == "corrupt":
                    ctl.inject(kind, rate=rate)
                    row["rate"] = round(rate, 3)
                else:
                    ctl.inject(kind)
        elif fault == "pilot_mode":
            rig.link.command(MAV_CMD_DO_SET_MODE, 1, LOITER)
        elif fault == "pilot_estop":
            rig.link.command(MAV_CMD_DO_AUX_FUNCTION, AUX_MOTOR_ESTOP, 2)
        elif fault == "script_error":
            row["script_state_hit"] = rig.link.script_state
            info = rig.link.info
            rig.link.conn.mav.param_set_send(
                info.system, info.component, b"SCR_USER1", 1.0, mavlink.MAV_PARAM_TYPE_REAL32
            )

    def fly_one(self, i: int) -> dict:
        a = self.a
        if self.rig is None or self.rig_landings >= a.per_vehicle:
            self.new_rig(i)
        try:
            self.ready_over_roof()
        except RestartVehicleError:
            self.new_rig(i)
            self.ready_over_roof()
        rig = self.rig
        # the recorder keeps what this landing reads, not the vehicle's whole life: the process's
        # memory then shows the companion's growth, not the recorder's (about 1.3 MB a landing)
        rig.track.trim(rig.now - 30.0)
        rng = self.rng = np.random.default_rng([a.seed, i])  # this landing's draws, whatever came before
        slope = rig.slope_deg
        v = float(rng.uniform(1.0, 2.5))
        p = self.table.lookup(slope, v)
        fall = max(0.0, (v * v - 0.25) / (2 * 9.80665))
        cut = round(contact_range(slope) + CONTACT_OFFSET_M + CUT_LATENCY_M + fall, 2)
        cfg = config(reflex={"cut_height_m": cut})
        names = list(self.faults)
        w = np.array([self.faults[n] for n in names], float)
        fault = str(rng.choice(names, p=w / w.sum()))
        target = str(rng.choice(KILL_STATES if fault == "companion_kill" else STATES))
        att = rig.link.last.get("ATTITUDE")
        row = {"i": i, "rig": self.rig_count, "slope": slope, "v": round(v, 2), "cut": cut,
               "yaw_deg": None if att is None else round(math.degrees(att.yaw), 1),
               "preset": [p.tau_up, p.tau_down], "angle_up": p.angle_up_deg, "fault": fault,
               "target": target}  # fmt: skip
        self.row = row
        if fault == "companion_kill":
            return self.fly_killed(row, p, cfg, target)
        if fault == "link_noise":
            noise = {
                k: round(float(rng.uniform(0.0, 0.1)), 3) for k in ("drop", "duplicate", "reorder", "corrupt")
            }
            noise.update(delay_s=round(float(rng.uniform(0.0, 0.05)), 3), jitter_s=0.02)
            rig.relay.set_faults(noise)
            row["noise"] = noise
        # the landing as `slopelander land` flies it: the session's lander, the table's uphill angle
        self.lander = lander = rig.session.make_lander(
            (p.tau_up, p.tau_down), uphill_angle_deg=p.angle_up_deg, slope_deg=rig.slope_deg, cfg=cfg
        )
        self.forever_until = None
        t0 = rig.now
        said0 = len(rig.track.statustext)
        fired = fault in ("none", "link_noise")
        seen = set()
        end = None
        took_off = False
        held_since = None
        wall0 = time.monotonic()
        try:
            while True:
                name = lander.poll()
                # held armed on the roof after a slide, the motors held, the pilot told: the
                # controller waits for the pilot and has no end of its own (as Rig.land ends it)
                if name == "SETTLED" and "slide" in lander.ctx.marks.get("said", set()):
                    held_since = rig.now if held_since is None else held_since
                    if rig.now - held_since >= HELD_S and self.forever_until is None:
                        end = "HELD"
                        break
                else:
                    held_since = None
                # the pilot's stick down while disarmed: ArduCopter's arming rule, which the
                # simulated vehicle holds too (arducopter_rules.arming_failure, RC_OPTIONS bit 5)
                rig.pilot_stick_down_while_disarmed()
                seen.update(h["to"] for h in lander.machine.history)
                if not fired and target in seen:
                    self.inject(fault, row)
                    fired = True
                if self.forever_until is not None and time.monotonic() > self.forever_until:
                    rig.relay.restore()
                    self.forever_until = None
                if lander.machine._started:
                    if name == "LANDED" and not took_off:
                        rig.wait(1.0, tick=lander.poll)
                        row["legs_on_ground"] = [lg.state.name for lg in rig.legs.status.legs] if (
                            rig.legs is not None and rig.legs.status is not None) else None  # fmt: skip
                        lander.takeoff_request = True
                        took_off = True
                    elif (
                        name in ("ABORTED", "ESTOP", "READY")
                        and self.forever_until is None
                        and not lander.abort_settling()  # as Lander.run: the script may still cut
                    ):
                        end = name
                        break
                    elif name == "LANDED" and lander.ctx.marks.get("takeoff_refused"):
                        # a faulted script is never flown again (states/landed.py): disarmed on
                        # the roof, legs clamped, the pilot told to reboot; the landing's end
                        end = "FAULT_LANDED"
                        break
                if rig.now - t0 > VEHICLE_LIMIT_S or time.monotonic() - wall0 > WALL_LIMIT_S:
                    end = "hang"
                    break
                rig.link.wait_readable(0.005)  # the autopilot's link only, as Lander.run
            if end != "hang":
                rig.wait(2.0, tick=lander.poll)
        finally:
            if self.forever_until is not None or fault.startswith("cut"):
                rig.relay.restore()
            if fault == "link_noise":
                rig.relay.set_faults({k: 0.0 for k in row["noise"]})
        rig.read_events()
        history = list(lander.machine.history)
        row.update(
            end=end,
            states=[h["to"] for h in history],
            t_end=round(rig.now, 3),
            wall_s=round(time.monotonic() - wall0, 2),
            reason=history[-1]["reason"],
        )
        if not fired:
            row["hit_state"] = "never reached"
        self.finish_row(row, t0, said0, cfg, history)
        if end == "hang":  # what the companion saw last, to tell why
            tr = rig.track
            row["last"] = {
                "range": tr.ranges[-1][1] if tr.ranges else None,
                "clearance": round(self.clearance(rig.now), 3),
                "armed": rig.armed(),
                "mode": rig.mode(),
                "script": rig.link.script_state,
                "range_ok": lander.inputs().range_ok,
            }
        self.rig_landings += 1
        if (
            fault in ("pilot_estop", "leg_unplug")
            or end in ("ESTOP", "hang")
            or (fault == "script_error" and fired)
        ):
            row["restart"] = fault if fault in ("pilot_estop", "leg_unplug", "script_error") else end
            self.restarts[row["restart"]] += 1
            self.close_rig()
        elif fault.startswith("leg_") or lander.legs is None:
            self.reopen_legs()
        return row

    def finish_row(self, row: dict, t0: float, said0: int, cfg, history: list[dict]) -> None:
        """The end state, the autopilot's and the script's words, the checks and the overlaps."""
        rig = self.rig
        row["after"] = {
            "armed": rig.armed(),
            "clearance": round(self.clearance(rig.now), 2),
            "clearance_reported": round(self.reported_clearance(rig.now), 2),
            "mode": rig.mode(),
            "servo": list(rig.track.servo[-1][1]) if rig.track.servo else None,
        }
        row["vehicle_said"] = [t for t in rig.track.statustext[said0:] if not t.startswith("SL ")][:12]
        row["script"] = [code for t, code in rig.track.script if t >= t0]
        row["unsafe"] = self.check(row, t0, cfg, history)
        seen = [f for f in self.scenario_faults if f["start"] < rig.now and f["end"] > t0]
        row["sensor_faults"] = sorted({f["kind"] for f in seen})
        row["sensor_fault_times"] = seen  # vehicle times: what overlapped what
        contact = rig.track.contact(t0)
        row["contact"] = None if contact is None else {k: round(v, 3) for k, v in contact.items()}
        row["stops"] = [round(t, 3) for t in rig.track.event_times("EV_STOP", t0)][:5]
        if row["unsafe"] and self.a.log is not None:
            row["trace"] = str(self.write_trace(row["i"], t0, history))

    def write_trace(self, i: int, t0: float, history: list[dict]) -> Path:
        """What the companion and the physics saw of an unsafe landing, beside the log
        (``<log>-trace-<i>.json``): the vehicle's reports since ``t0`` (position, pitch, range,
        motor outputs, the script's states and events, status texts), the physics' true height
        over the roof on ArduCopter, and the landing's transitions with their reasons. Enough to
        read the landing afterwards; the rig keeps only the last half minute of its vehicle."""
        tr = self.rig.track
        series = ("pos", "pitch", "ranges", "servo", "script")
        keep = {name: [p for p in getattr(tr, name) if p[0] >= t0] for name in series}
        keep["events"] = [e for e in tr.events if e[1] >= t0]
        keep["statustext"] = tr.statustext[-60:]
        keep["history"] = history
        keep["slope_deg"] = self.rig.slope_deg
        keep["clearance"] = [(round(t, 3), round(self.clearance(t), 3)) for t, *_ in keep["pos"][::5]]
        dest = Path(f"{self.a.log.with_suffix('')}-trace-{i}.json")
        dest.write_text(json.dumps(keep, default=str))
        return dest

    def fly_killed(self, row: dict, p, cfg, target: str) -> dict:
        """The landing flown by a companion process of its own, killed (SIGKILL) in ``target``;
        watched on the autopilot's second port; the vehicle is started afresh after it."""
        rig = self.rig
        wall0 = time.monotonic()
        t0 = rig.now
        watch = Session(
            rig.vehicle.gcs_url,
            config(link=dict(RIG_RATES)),
            decode=TRACK_MESSAGES,
            telemetry=False,
            lockstep=False,
        )
        watch.link.add_listener(rig.track.listen)
        try:
            watch_streams(watch)
        except BaseException:
            watch.close()
            raise
        rig.session.close()  # the rig's companion leaves the link and the board to the process
        rig.session, rig.link, rig.legs = watch, watch.link, None
        said0 = len(rig.track.statustext)
        cmd = [sys.executable, str(REPO / "benchmarks" / "soak_companion.py"), "--url",
               f"tcp:127.0.0.1:{rig.relay.port}", "--legs", rig.board.pty, "--slope", f"{rig.slope_deg}",
               "--preset", f"{p.tau_up}", f"{p.tau_down}", "--angle-up", f"{p.angle_up_deg}",
               "--cut", f"{cfg['reflex.cut_height_m']}"]  # fmt: skip
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        lines: list[dict] = []
        err: list[str] = []

        def read(stream, into, parse) -> None:
            for ln in stream:
                if parse:
                    try:
                        into.append(json.loads(ln))
                    except ValueError:
                        err.append(ln.rstrip())
                else:
                    into.append(ln.rstrip())

        readers = [
            threading.Thread(target=read, args=(proc.stdout, lines, True), daemon=True),
            threading.Thread(target=read, args=(proc.stderr, err, False), daemon=True),
        ]
        for t in readers:
            t.start()
        killed_at = None
        end = None
        try:
            while True:
                rig.poll()
                history = [x for x in list(lines) if "to" in x]
                if killed_at is None and any(h["to"] == target for h in history):
                    proc.kill()
                    proc.wait()
                    killed_at = rig.now
                    row.update(hit_state=history[-1]["to"], hit_t=round(killed_at, 3))
                    break
                if proc.poll() is not None:  # it ended (or failed) before the target
                    proc.wait()
                    break
                if rig.now - t0 > VEHICLE_LIMIT_S or time.monotonic() - wall0 > WALL_LIMIT_S:
                    proc.kill()
                    proc.wait()
                    end = "hang"
                    break
                time.sleep(0.002)
            for t in readers:
                t.join(2.0)
            t_watch = rig.now
            rig.wait(KILLED_WATCH_S)  # nobody on the companion's port: what does the vehicle do?
            if rig.now - t_watch < KILLED_WATCH_S - 0.5:
                raise RigError(
                    f"the vehicle's clock did not run on after the kill ({rig.now - t_watch:.1f} s)"
                )
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        rig.read_events()
        history = [x for x in lines if "to" in x]
        if end is None:
            end = (
                "killed"
                if killed_at is not None
                else next((x["end"] for x in lines if "end" in x), "companion error")
            )
        row.update(
            end=end,
            states=[h["to"] for h in history],
            t_end=round(rig.now, 3),
            wall_s=round(time.monotonic() - wall0, 2),
            reason=history[-1]["reason"]
            if history
            else "; ".join([str(x.get("error")) for x in lines if "error" in x] + err[-3:]),
        )
        if killed_at is None:
            row["hit_state"] = "never reached"
        self.finish_row(row, t0, said0, cfg, history)
        self.rig_landings += 1
        row["restart"] = "companion_kill"
        self.restarts["companion_kill"] += 1
        self.close_rig()
        return row

    # --------------------------------------------------------------------------- checks
    def clearance(self, t: float) -> float:
        """Height (m) of the body above the roof below it at vehicle time ``t``, counted as the
        vehicle's LOCAL_POSITION_NED counts it (from home, :attr:`Rig.home_range_m` over the pad).
        On ArduCopter from the physics' true height (its ``TR_H`` events, every 50 ms): the
        autopilot reports its EKF's estimate, which put a cut 0.27 m too high and legs loosened
        0.40 m too low on a 23 deg roof in the first soak. Where no true height is near, as
        :meth:`reported_clearance`."""
        h = self.true_height(t) if self.real else None
        if h is not None:
            return h - self.rig.home_range_m
        return self.reported_clearance(t)

    def true_height(self, t: float) -> float | None:
        """The physics' height (m) of the body over the surface at ``t``, interpolated between its
        TR_H samples; None without one within 0.2 s."""
        ev = self.rig.track.events
        if self._truth is None or self._truth[0] != (id(ev), len(ev)):
            self._truth = ((id(ev), len(ev)), sorted((tt, v) for n, tt, v in ev if n == "TR_H"))
        h = self._truth[1]
        i = bisect.bisect_left(h, (t,))
        if 0 < i < len(h):
            (t0, h0), (t1, h1) = h[i - 1], h[i]
            if t1 - t0 <= 0.2:
                return h0 + (h1 - h0) * (t - t0) / (t1 - t0) if t1 > t0 else h1
        near = [s for s in h[max(0, i - 1) : i + 1] if abs(s[0] - t) <= 0.2]
        return near[0][1] if near else None

    def reported_clearance(self, t: float) -> float:
        """Height (m) of the body above the roof below it at vehicle time ``t``, interpolated
        between the position samples around it. The samples are put in time order first: the
        recorder keeps them in arrival order, which a link that reorders frames shuffles (a
        binary search over them once gave a sample from before the climb)."""
        pos = self.rig.track.pos
        key = (id(pos), len(pos))
        if self._pos_sorted is None or self._pos_sorted[0] != key:
            self._pos_sorted = (key, sorted(pos))
        ordered = self._pos_sorted[1]
        i = bisect.bisect_left(ordered, (t,))
        if i == 0 or i == len(ordered):
            _, x, z, _, _ = ordered[min(i, len(ordered) - 1)]
            return z - self.rig.surface_z(x)
        (t0, x0, z0, _, _), (t1, x1, z1, _, _) = ordered[i - 1], ordered[i]
        w = 0.0 if t1 <= t0 else (t - t0) / (t1 - t0)
        x, z = x0 + w * (x1 - x0), z0 + w * (z1 - z0)
        return z - self.rig.surface_z(x)

    def range_height(self, t: float) -> float:
        """What a level body's rangefinder reads at vehicle time ``t``: the height over the roof plus
        home's height over the pad. The cut and the take-off's clear height are range thresholds."""
        return self.clearance(t) + self.rig.home_range_m

    def check(self, row: dict, t0: float, cfg, history: list[dict]) -> list[str]:
        rig, tr = self.rig, self.rig.track
        bad = []
        estop = row["fault"] == "pilot_estop" and row.get("hit_state") not in (None, "never reached")
        if row["end"] == "hang":
            bad.append("hang")
        contacts = tr.event_times("EV_CONTACT", t0)
        first_contact = min(contacts, default=math.inf)
        for t in tr.event_times("EV_STOP", t0):
            if not estop and self.range_height(t) > row["cut"] + 0.25:
                if t < first_contact:
                    bad.append(f"stop_high@{t:.2f}:{self.range_height(t):.2f}m")
                else:
                    row.setdefault("stops_after_contact", []).append(f"{t:.2f}:{self.range_height(t):.2f}m")
        stops = tr.event_times("EV_STOP", t0)
        if contacts and not any(t <= first_contact for t in stops):
            bad.append(f"contact_under_power@{first_contact:.2f}")
        for t in tr.event_times("EV_RVT", t0):
            if not any(t - 2.0 <= c <= t + 0.01 for c in contacts) and self.clearance(t) > ON_ROOF_M:
                bad.append(f"reverse_in_air@{t:.2f}")
        h = self.clearance(rig.now)
        servo = tr.servo[-1][1] if tr.servo else ()
        if h > ON_ROOF_M and not estop:
            if rig.armed() and stopped(servo):
                bad.append("armed_stopped_in_air")
            if not rig.armed():
                bad.append(f"disarmed_in_air:{h:.2f}m")
        if h <= ON_ROOF_M and rig.armed() and servo and not stopped(servo):
            bad.append(f"armed_on_roof_unheld:{h:.2f}m,{'/'.join(map(str, servo))}us")
        if "LANDED" in row["states"] and row.get("legs_on_ground") and "LOOSE" in row["legs_on_ground"]:
            bad.append("legs_loose_on_ground")
        reset = next((e for e in history if e["to"] == "RESET"), None)
        if reset is not None and self.range_height(reset["t"]) < cfg["takeoff.clear_height_m"] - 0.1:
            # with what the machine believed: "clear of the ground at <height> m ..."
            bad.append(f"legs_loosened_low:{self.range_height(reset['t']):.2f}m ({reset['reason']})")
        return bad


def fit_slope(xs: list[float], ys: list[float]) -> float:
    return float(np.polyfit(xs, ys, 1)[0]) if len(xs) > 2 else math.nan


#: the settings a resumed run must share with the log's first line
RUN_KEYS = ("seed", "autopilot", "per_vehicle", "slopes", "speed", "speedup", "faults")


def read_log(path: Path) -> tuple[dict | None, list[dict]]:
    """A soak log's settings line (None in logs from before it was written) and its landings. A
    last line cut short by a killed run is left out (it is flown again on ``--resume``)."""
    head, rows = None, []
    lines = path.read_text().splitlines()
    for n, ln in enumerate(lines, 1):
        if not ln.strip():
            continue
        try:
            d = json.loads(ln)
        except ValueError as exc:
            if n == len(lines):
                print(f"{path}:{n}: a line cut short, left out", file=sys.stderr)
                continue
            raise ValueError(f"line {n}: {exc}") from None
        if "run" in d:
            head = d["run"]
        else:
            rows.append(d)
    return head, rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--landings", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--per-vehicle", type=int, default=None, help="landings per vehicle process (25; 10 on ArduCopter)"
    )
    ap.add_argument("--speed", type=float, default=8.0, help="vehicle's most simulated s per wall s")
    ap.add_argument("--minutes", type=float, default=math.inf, help="start no landing after this (wall)")
    ap.add_argument("--log", type=Path, default=None, help="append one JSON line per landing here")
    ap.add_argument("--resume", action="store_true", help="fly the landings --log does not hold yet")
    ap.add_argument(
        "--slopes", type=float, nargs=2, default=None, metavar=("LO", "HI"),
        help="roof slopes drawn (deg; 15 45, on ArduCopter 0 55)",
    )  # fmt: skip
    ap.add_argument(
        "--results",
        type=Path,
        default=REPO / "benchmarks" / "results",
        help="folder the dated table goes to (with --log; '-' for none)",
    )
    ap.add_argument(
        "--faults",
        type=lambda t: sorted(t.split(",")),
        default=None,
        metavar="NAME,NAME",
        help="draw only these faults (their usual weights), e.g. companion_kill,script_error",
    )
    add_autopilot_args(ap)
    ap.add_argument(
        "--report",
        type=Path,
        nargs="+",
        default=None,
        help="print the tables of earlier runs' logs (several: one table; each run's growth on its own)",
    )
    a = ap.parse_args()
    real = a.autopilot == "ardupilot"
    if a.per_vehicle is None:
        a.per_vehicle = 10 if real else 25
    if a.slopes is None:
        a.slopes = [0.0, 55.0] if real else [15.0, 45.0]
    if a.landings < 1 or a.per_vehicle < 1:
        ap.error("--landings and --per-vehicle must be at least 1")
    if not (0.0 <= a.slopes[0] <= a.slopes[1] <= 60.0):
        ap.error(f"--slopes: LO <= HI within 0..60 deg, got {a.slopes[0]:g} {a.slopes[1]:g}")
    if a.faults and not set(a.faults) <= set(faults_for(a.autopilot)):
        unknown = ", ".join(sorted(set(a.faults) - set(faults_for(a.autopilot))))
        ap.error(f"--faults: {unknown} not among {', '.join(faults_for(a.autopilot))} ({a.autopilot})")
    if gust_count(a.per_vehicle) > MAX_GUSTS:
        # else every vehicle refuses its scenario and each landing is a rig error
        ap.error(f"--per-vehicle: at most {MAX_PER_VEHICLE} (a vehicle's scenario holds {MAX_GUSTS} gusts)")
    if a.report:
        runs = []
        for path in a.report:
            try:
                runs.append((str(path), read_log(path)[1]))
            except (OSError, ValueError) as exc:
                ap.error(f"{path}: cannot read the soak log: {exc}")
        report(runs)
        return
    if real:
        from slopelander_sitl.ardupilot.launch import ArduCopterMissingError, arducopter_binary

        try:
            arducopter_binary(a.arducopter)
        except ArduCopterMissingError as exc:
            ap.error(str(exc))
    settings = {k: getattr(a, k) for k in RUN_KEYS}
    done: list[dict] = []
    if a.resume:
        if a.log is None or not a.log.exists():
            ap.error("--resume needs --log naming the log of the run to go on with")
        try:
            head, done = read_log(a.log)
        except (OSError, ValueError) as exc:
            ap.error(f"{a.log}: cannot read the soak log: {exc}")
        if head is not None:
            differ = {k: (head.get(k), v) for k, v in settings.items() if head.get(k) != v}
            if differ:
                ap.error(
                    f"{a.log} was flown with other settings: "
                    + ", ".join(f"--{k.replace('_', '-')} {h} (now {v})" for k, (h, v) in differ.items())
                )
    elif a.log is not None and a.log.exists() and a.log.stat().st_size:
        ap.error(f"{a.log} exists: --resume to go on with it, or name another log")
    soak = Soak(a)
    flown = {r["i"] for r in done}
    todo = [i for i in range(a.landings) if i not in flown]
    rows = list(done)
    log = open(a.log, "a") if a.log else None  # noqa: SIM115
    if log and not done and log.tell() == 0:
        log.write(json.dumps({"run": settings, "started": time.strftime("%Y-%m-%d %H:%M:%S")}) + "\n")
        log.flush()
    wall0 = time.monotonic()
    wall_before = max((r.get("wall_t", 0.0) for r in done), default=0.0)

    def alarm(signum, frame):
        raise HangError("wall-time limit")

    signal.signal(signal.SIGALRM, alarm)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # stop the vehicle and board on the way out
    try:
        bar = tqdm(todo, unit="landing", file=sys.stderr, initial=len(flown), total=a.landings)
        for i in bar:
            if time.monotonic() - wall0 > 60.0 * a.minutes:
                print(f"stopped after {a.minutes:g} min (--minutes)", file=sys.stderr)
                break
            signal.alarm(int(WALL_LIMIT_S + 120))
            try:
                row = soak.fly_one(i)
            except Exception as exc:  # recorded: a rig error, or a crash the table shows by type
                row = soak.row if soak.row.get("i") == i else {"i": i, "fault": "-"}
                row.update(
                    {
                        "rig": soak.rig_count,
                        "end": "rig error",
                        "reason": f"{type(exc).__name__}: {exc}",
                        "unsafe": ["hang"] if isinstance(exc, HangError) else [],
                        "restart": "rig error",
                    }
                )
                soak.restarts["rig error"] += 1
                soak.close_rig()
            finally:
                signal.alarm(0)
            row["resources"] = resources()
            row["wall_t"] = round(wall_before + time.monotonic() - wall0, 1)
            rows.append(row)
            bar.set_postfix(unsafe=sum(1 for r in rows if r.get("unsafe")), refresh=False)
            if log:
                log.write(json.dumps(row) + "\n")
                log.flush()
    finally:
        soak.close_rig()
        soak._tmp.cleanup()
        if log:
            log.close()
    rows.sort(key=lambda r: r["i"])
    out = io.StringIO()
    report([(str(a.log or "this run"), rows)], out)
    print(out.getvalue(), end="")
    if a.log is not None and str(a.results) != "-":
        a.results.mkdir(parents=True, exist_ok=True)
        name = "arducopter" if real else "sim"
        dest = a.results / f"{date.today().isoformat()}-soak-{name}.txt"
        cmd = "python3 benchmarks/soak.py " + " ".join(sys.argv[1:])
        load = os.getloadavg()[0]
        dest.write_text(
            f"# {date.today().isoformat()} {cmd}\n# log {a.log}; {len(rows)} of {a.landings} landings; "
            f"resume: the same command with --resume; load average {load:.1f} at the end, 2-core machine\n"
            + out.getvalue()
        )
        print(f"table written to {dest}", file=sys.stderr)


def report(runs: list[tuple[str, list[dict]]], out=None) -> None:
    """The outcome table over every run's landings (to ``out``, else stdout); each run's process
    growth on its own."""

    def say(*args) -> None:
        print(*args, file=out or sys.stdout)

    rows = [r for _, rs in runs for r in rs]
    n = len(rows)
    if not n:
        say("no landings")
        return
    wall = sum(max((r.get("wall_t", 0.0) for r in rs), default=0.0) for _, rs in runs)
    # a vehicle's landings are in a row; a resumed run numbers its vehicles from 1 again
    rigs = sum(1 + sum(1 for a, b in pairwise(rs) if a.get("rig") != b.get("rig")) for _, rs in runs if rs)
    say(
        f"\n{n} landings on {rigs} vehicles in {len(runs)} run(s), {wall:.0f} s wall in all "
        f"({wall / n:.1f} s per landing)"
    )
    ends = sorted({r["end"] for r in rows})
    say(f"\n{'fault':<16} {'n':>4}  " + "  ".join(f"{e:>9}" for e in ends) + "  unsafe")
    for fault in [*ARDUPILOT_FAULTS, "-"]:
        rs = [r for r in rows if r["fault"] == fault]
        if not rs:
            continue
        c = Counter(r["end"] for r in rs)
        say(f"{fault:<16} {len(rs):>4}  " + "  ".join(f"{c[e]:>9}" for e in ends)
              + f"  {sum(1 for r in rs if r['unsafe']):>6}")  # fmt: skip
    say("\nstate hit by an injected fault (faults other than none/link_noise):")
    hit = Counter(r.get("hit_state") for r in rows if r.get("hit_state"))
    say("  " + ", ".join(f"{k} {v}" for k, v in sorted(hit.items(), key=lambda kv: -kv[1])))
    sens = Counter(k for r in rows for k in r.get("sensor_faults", []))
    say("sensor faults overlapping a landing: " + (", ".join(f"{k} {v}" for k, v in sens.items()) or "none"))
    reasons = Counter(r["reason"].split(":")[0][:48] for r in rows if r["end"] in ("ABORTED", "rig error"))
    say("abort / error reasons:")
    for k, v in reasons.most_common():
        say(f"  {v:4d}  {k}")
    restarts = Counter(r["restart"] for r in rows if r.get("restart"))
    say(
        "vehicle restarts besides the scheduled ones: "
        + (", ".join(f"{k} {v}" for k, v in restarts.items()) or "none")
    )
    unsafe = [r for r in rows if r["unsafe"]]
    hangs = [r for r in rows if "hang" in r["unsafe"]]
    say(f"\nhangs: {len(hangs)}; unsafe ends: {len(unsafe)}")
    kinds = Counter(u.split("@")[0].split(":")[0] for r in unsafe for u in r["unsafe"])
    if kinds:
        say("unsafe ends by class: " + ", ".join(f"{k} {v}" for k, v in kinds.most_common()))
    for r in unsafe[:40]:
        say(
            f"  landing {r['i']}: {r['fault']} in {r.get('hit_state')}: {r['unsafe']} "
            f"({r['end']}: {r['reason']})"
        )
    for name, rs in runs:
        samples = [(r["i"], r["resources"]) for r in rs if "resources" in r]
        if len(samples) < 3:
            continue
        xs = [i for i, _ in samples]
        half = len(samples) // 2
        say(f"\ncompanion process of {name}  first   last   slope per 100 landings (second half)")
        for k in ("rss_mb", "heap_used_mb", "heap_kept_free_mb", "threads", "fds"):
            if not all(k in res for _, res in samples):  # logs from before it was recorded
                continue
            ys = [res[k] for _, res in samples]
            say(f"  {k:<26} {ys[0]:6.1f} {ys[-1]:6.1f}   {100 * fit_slope(xs[half:], ys[half:]):+.2f}")


if __name__ == "__main__":
    main()
