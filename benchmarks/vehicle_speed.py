"""How many times faster than real time the simulated vehicle runs at --speed 0 (as fast as
it can), measured from its own clock in SYSTEM_TIME against the wall clock, on the pad and
while hovering in GUIDED. Prints the figures; takes about 40 s (most of it the model's compile).

    python benchmarks/vehicle_speed.py [--script FILE | --no-script] [--seconds 10]
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

from sitl.vehicle.launch import start_vehicle  # noqa: E402

M = mavutil.mavlink


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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--script", type=Path, default=None)
    ap.add_argument("--no-script", action="store_true")
    ap.add_argument("--seconds", type=float, default=10.0)
    a = ap.parse_args()
    params = {"MOT_PWM_MIN": 1525, "MOT_PWM_MAX": 2000}
    v = start_vehicle(params=params, script=a.script, no_script=a.no_script, speed=0.0)
    try:
        conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255)
        conn.wait_heartbeat(timeout=10)
        conn.mav.command_long_send(1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, M.MAVLINK_MSG_ID_SYSTEM_TIME,
                                   100000, 0, 0, 0, 0, 0)
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
