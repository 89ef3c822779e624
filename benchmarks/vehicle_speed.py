"""How many times faster than real time the simulated vehicle runs, measured from its own clock
against the wall clock:

1. free-running at --speed 0 (as fast as it can), from SYSTEM_TIME, on the pad and while
   hovering in GUIDED;
2. in lock-step (--lockstep --speed 0) with the on-board script and the simulated leg board
   running, during a whole reflex landing on the roof: this client plays the companion's part
   in the lock-step (a TIMESYNC echo of the newest vehicle time every 20 ms of vehicle time,
   streams at the companion's rates), presets the legs over the serial link with the LegBoard
   driver, takes off, flies over the roof, arms the script's reflex and descends until the
   vehicle's landing record arrives.

Prints the figures; takes about 1.5 min (much of it the model's compile in each new process).

    python benchmarks/vehicle_speed.py [--script FILE | --no-script] [--seconds 10]
        [--slope 20] [--board-speed 2] [--skip-free] [--board-cost]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from pymavlink import mavutil  # noqa: E402

from slopelander.legs import LegBoard  # noqa: E402
from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle  # noqa: E402

M = mavutil.mavlink
USER_2 = 31011  # the script's reflex command
ECHO_EVERY_S = 0.02  # the companion's TIMESYNC echo period (vehicle time)
TIME_FIELDS = {"time_usec": 1e-6, "time_boot_ms": 1e-3}
COMPANION_STREAMS = (
    (M.MAVLINK_MSG_ID_HIGHRES_IMU, 200),
    (M.MAVLINK_MSG_ID_ATTITUDE, 50),
    (M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 50),
    (M.MAVLINK_MSG_ID_SYSTEM_TIME, 10),
)


def rate(conn, wall_s: float) -> float:
    conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=5)
    a = conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=5)
    t0 = time.monotonic()
    b = a
    while time.monotonic() - t0 < wall_s:
        m = conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=1)
        if m is not None:
            b = m
    return (b.time_boot_ms - a.time_boot_ms) / 1000.0 / (time.monotonic() - t0)


class LockstepClient:
    """The companion's side of the lock-step: every message read moves the newest vehicle time
    seen; every 20 ms of it a TIMESYNC echo lets the vehicle run on."""

    def __init__(self, conn) -> None:
        self.conn, self.t, self.echoed = conn, 0.0, -1.0
        self.record: dict[str, float] = {}
        self.last: dict[str, object] = {}
        self.requests = 0  # the on-board script's request numbers sent

    def pump(self, wall_timeout: float = 0.01) -> None:
        m = self.conn.recv_match(blocking=True, timeout=wall_timeout)
        while m is not None:
            kind = m.get_type()
            self.last[kind] = m
            for name, scale in TIME_FIELDS.items():
                if kind != "TIMESYNC" and hasattr(m, name):
                    self.t = max(self.t, getattr(m, name) * scale)
            if kind == "NAMED_VALUE_FLOAT" and m.name.startswith(("TD_", "LD_")):
                self.record[m.name] = m.value
            m = self.conn.recv_match(blocking=False)
        if self.t - self.echoed >= ECHO_EVERY_S:
            self.conn.mav.timesync_send(int(self.t * 1e9), int(self.t * 1e9))
            self.echoed = self.t

    def command(self, cmd: int, *p: float) -> int:
        self.last.pop("COMMAND_ACK", None)
        self.conn.mav.command_long_send(1, 1, cmd, 0, *(list(p) + [0.0] * (7 - len(p))))
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            self.pump()
            ack = self.last.get("COMMAND_ACK")
            if ack is not None and ack.command == cmd:
                return ack.result
        raise SystemExit(f"no COMMAND_ACK for {cmd}")

    def script_command(self, cmd: int, *p: float) -> int:
        """A command to the on-board script: its param 7 is the request number, counted from 1
        (slopelander.controller.script_contract; the script refuses a command without one)."""
        self.requests += 1
        return self.command(cmd, *(list(p) + [0.0] * (6 - len(p))), float(self.requests))

    def until(self, cond, wall_timeout: float = 60.0, every=None) -> None:
        """Pump until ``cond()``; ``every()`` runs every 0.1 s of vehicle time meanwhile."""
        deadline, next_t = time.monotonic() + wall_timeout, 0.0
        while not cond():
            if time.monotonic() > deadline:
                raise SystemExit("the landing did not finish in time")
            self.pump()
            if every is not None and self.t >= next_t:
                every()
                next_t = self.t + 0.1


def lockstep_landing(script, slope_deg: float, board_speed: float) -> None:
    lb = start_legboard(speed=board_speed)
    try:
        board = LegBoard.open(lb.pty)
        try:
            board.set_torques(uphill=1.7, downhill=1.7)
        finally:
            board.close()
        params = {"MOT_PWM_MIN": 1525, "MOT_PWM_MAX": 2000}
        v = start_vehicle(
            params=params,
            script=script,
            speed=0.0,
            lockstep=True,
            legboard_control=lb.control,
            scenario={"slope_deg": slope_deg, "seed": 1},
        )
        try:
            conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255)
            conn.wait_heartbeat(timeout=10)
            c = LockstepClient(conn)
            for msg, hz in COMPANION_STREAMS:
                c.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, msg, 1e6 / hz)
            wall0, t0 = time.monotonic(), c.t
            assert c.command(M.MAV_CMD_DO_SET_MODE, 1, 4) == 0
            assert c.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
            assert c.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 2.5) == 0

            def pos():
                return c.last.get("LOCAL_POSITION_NED")

            c.until(lambda: pos() is not None and pos().z < -2.4)
            conn.mav.set_position_target_local_ned_send(
                0, 1, 1, M.MAV_FRAME_LOCAL_NED, 0x0DF8, 4.5, 0, -2.5, 0, 0, 0, 0, 0, 0, 0, 0
            )
            c.until(lambda: abs(pos().x - 4.5) < 0.2 and abs(pos().vx) < 0.2)
            arm = (1, 0.3, 20, 100, 5000, 5000)  # ARM: cut m, impact m/s^2, reverse %, ms, validity ms
            assert c.script_command(USER_2, 3, 0, 0.5) == 0  # SETUP: no ramp, 0.5 m/s descent
            assert c.script_command(USER_2, *arm) == 0
            t_armed = c.t

            def descend():
                conn.mav.set_position_target_local_ned_send(
                    0, 1, 1, M.MAV_FRAME_LOCAL_NED, 0x0DC7, 0, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0
                )
                if c.t - t_armed > 1.0:  # the refresh, answered as the landing goes on
                    c.requests += 1
                    conn.mav.command_long_send(1, 1, USER_2, 0, *arm, float(c.requests))

            c.until(lambda: "LD_DONE" in c.record, every=descend)
            wall, sim = time.monotonic() - wall0, c.t - t0
            conn.close()
        finally:
            v.stop()
    finally:
        lb.stop()
    outcome = int(c.record["LD_OUTCOME"])
    print(
        f"lock-step, script and leg board, whole landing on a {slope_deg:g} deg roof (take-off, "
        f"transit, reflex descent, touchdown to the model's decision): {sim / wall:.1f} x real time "
        f"({sim:.1f} s vehicle time in {wall:.1f} s; outcome code {outcome})"
    )


def lockstep_hover(with_board: bool, board_speed: float, seconds: float) -> float:
    """Lock-step speed while hovering in GUIDED (script running), with or without the leg board."""
    lb = start_legboard(speed=board_speed) if with_board else None
    try:
        v = start_vehicle(
            params={"MOT_PWM_MIN": 1525, "MOT_PWM_MAX": 2000},
            speed=0.0,
            lockstep=True,
            legboard_control=lb.control if lb else None,
        )
        try:
            conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255)
            conn.wait_heartbeat(timeout=10)
            c = LockstepClient(conn)
            for msg, hz in COMPANION_STREAMS:
                c.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, msg, 1e6 / hz)
            c.command(M.MAV_CMD_DO_SET_MODE, 1, 4)
            c.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            c.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 2.5)
            wall0, t0 = time.monotonic(), c.t
            c.until(lambda: c.t - t0 >= seconds)
            rate = (c.t - t0) / (time.monotonic() - wall0)
            conn.close()
        finally:
            v.stop()
    finally:
        if lb is not None:
            lb.stop()
    return rate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--script", type=Path, default=None)
    ap.add_argument("--no-script", action="store_true")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--slope", type=float, default=20.0, help="roof slope of the lock-step landing (deg)")
    ap.add_argument(
        "--board-speed",
        type=float,
        default=2.0,
        help="leg board's --speed, about the vehicle's (the board only holds during the landing)",
    )
    ap.add_argument("--skip-free", action="store_true", help="only the lock-step landing")
    ap.add_argument(
        "--board-cost",
        action="store_true",
        help="also: lock-step hover (10 s vehicle time) without and with the leg board",
    )
    a = ap.parse_args()
    if a.no_script:
        print("the lock-step landing needs the script: skipped")
    if not a.skip_free:
        free_running(a)
    if not a.no_script:
        lockstep_landing(a.script, a.slope, a.board_speed)
    if a.board_cost:
        for with_board in (False, True):
            r = lockstep_hover(with_board, a.board_speed, 10.0)
            print(
                f"lock-step hover, script, {'with' if with_board else 'without'} the leg board: "
                f"{r:.1f} x real time"
            )


def free_running(a: argparse.Namespace) -> None:
    params = {"MOT_PWM_MIN": 1525, "MOT_PWM_MAX": 2000}
    v = start_vehicle(params=params, script=a.script, no_script=a.no_script, speed=0.0)
    try:
        conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255)
        conn.wait_heartbeat(timeout=10)
        conn.mav.command_long_send(
            1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, M.MAVLINK_MSG_ID_SYSTEM_TIME, 100000, 0, 0, 0, 0, 0
        )
        print(f"script: {'none' if a.no_script else (a.script or 'default')}")
        print(f"on the pad, disarmed: {rate(conn, a.seconds):.1f} x real time")
        conn.mav.command_long_send(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 4, 0, 0, 0, 0, 0)
        conn.mav.command_long_send(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        time.sleep(0.2)
        conn.mav.command_long_send(1, 1, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 2.0)
        print(f"GUIDED take-off and hover: {rate(conn, a.seconds):.1f} x real time")
        conn.close()
    finally:
        v.stop()


if __name__ == "__main__":
    main()
