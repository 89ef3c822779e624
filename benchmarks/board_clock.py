"""The simulated leg board's clock in a lock-stepped flight: the wall clock (``--clock wall``,
board time = speed x wall time) against the vehicle's clock (``--clock external``, the vehicle
feeds the board its time every exchange).

For each setting: the leg board and a lock-stepped vehicle (``--speed S``) as processes, this
client as the companion (the controller's ``Link``, which echoes TIMESYNC, and the ``LegBoard``
driver on the vehicle-following clock, as the landing controller runs it). It alternates the
legs between two presets and prints, per setting: how long each preset took to settle as the
driver sees it in vehicle time and as the board reports it in board time, how far board time ran
from vehicle time over the run, and the vehicle's speed against the wall clock. ``--load N``
runs N busy processes meanwhile (the drift a loaded machine causes is the point).

First it times, in board seconds, the pilot's angle-changing preset switch of the flight tests on
an external-clock board alone (``--switch-only``: just that, a few seconds).

    python3 benchmarks/board_clock.py [--speed 8] [--presets 4] [--load 0] [--switch-only]
        [--settings wall:20,external:20,external:5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from slopelander.controller.link import Link  # noqa: E402
from slopelander.legs import LegBoard  # noqa: E402
from slopelander_sitl.legboard.control import BoardControl  # noqa: E402
from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle  # noqa: E402

PRESETS = ((1.2, 1.2), (2.0, 2.0))  # N*m, uphill and downhill pair; alternated
TOLERANCE_NM = 0.15


def switch_times(step_s: float = 0.02) -> list[tuple[str, float]]:
    """Board seconds of each step of the pilot's angle-changing preset switch (as in
    tests/controller/test_flight_safety.py): an external-clock board process fed ``step_s`` at a
    time over its control socket, the driver on the same clock."""
    board = start_legboard(clock="external")
    legs = None
    try:
        legs = LegBoard.open(board.pty)  # the board answers HELLO whatever its time
        now = [0.0]
        legs.set_clock(lambda: now[0])
        out = []
        with BoardControl(board.control) as ctl:
            for what, start in (
                (
                    "legs set 1.7 / 2.3 N*m from loose",
                    lambda: legs.start_presets(1.7, 2.3, tolerance_nm=0.15, timeout=60),
                ),
                (
                    "uphill legs re-angled 37.5 -> 25 deg",
                    lambda: legs.start_angles({0: 25.0, 1: 25.0}, timeout=60),
                ),
                (
                    "all four clamped at 2.5 N*m",
                    lambda: legs.start_presets(2.5, 2.5, tolerance_nm=0.15, timeout=60),
                ),
            ):
                op, t0 = start(), now[0]
                while not op.done:
                    now[0] += step_s
                    ctl.advance(now[0])
                    legs.poll()
                op.result()  # raises if it failed
                out.append((what, now[0] - t0))
        return out
    finally:
        if legs is not None:
            legs.close()
        board.stop()


def pump(link: Link, legs: LegBoard, wall_s: float = 0.001) -> None:
    link.poll()
    legs.poll()
    time.sleep(wall_s)


def run(clock: str, period_ms: float, speed: float, presets: int) -> dict:
    board = start_legboard(speed=speed, clock=clock)
    vehicle = link = legs = None
    try:
        vehicle = start_vehicle(
            scenario={"slope_deg": 0.0, "seed": 1},
            no_script=True,
            speed=speed,
            lockstep=True,
            legboard_control=board.control,
            legboard_period_ms=period_ms,
        )
        link = Link(vehicle.mavlink_url, link_loss_s=5.0, lockstep=True)
        link.wait_autopilot(timeout_s=30.0)
        for msg_id, hz in ((mavlink.MAVLINK_MSG_ID_RAW_IMU, 200), (mavlink.MAVLINK_MSG_ID_SYSTEM_TIME, 10)):
            h = link.request_stream(msg_id, hz)
            end = time.monotonic() + 10
            while not h.done and time.monotonic() < end:
                link.poll()
                time.sleep(0.002)
        legs = LegBoard.open(board.pty)
        legs.set_clock(link.clock.now)  # vehicle time, as the landing session (Session.open_legs)
        legs.silence_timeout = 5.0
        vehicle_s, board_s = [], []
        wall0, t0, b0 = time.monotonic(), link.clock.now(), None
        for i in range(presets):
            up, down = PRESETS[i % 2]
            op = legs.start_presets(up, down, tolerance_nm=TOLERANCE_NM, timeout=60.0)
            ts = link.clock.now()
            end = time.monotonic() + 120
            while not op.done and time.monotonic() < end:
                pump(link, legs)
                if b0 is None and legs.status is not None:
                    b0 = legs.status.board_time_s
            if not op.done:
                raise SystemExit(f"{clock}: preset {i} did not settle in 120 wall s")
            results = op.result()
            vehicle_s.append(link.clock.now() - ts)
            board_s.append(max(r.board_seconds or 0.0 for r in results.values()))
        wall = time.monotonic() - wall0
        dv = link.clock.now() - t0
        db = legs.status.board_time_s - b0
        return {
            "vehicle_s": vehicle_s,
            "board_s": board_s,
            "drift_s": db - dv,
            "vehicle_speed": dv / wall,
        }
    finally:
        if legs is not None:
            legs.close()
        if link is not None:
            link.close()
        if vehicle is not None:
            vehicle.stop()
        board.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speed", type=float, default=8.0, help="vehicle (and wall board) speed, as the rig")
    ap.add_argument("--presets", type=int, default=4)
    ap.add_argument("--load", type=int, default=0, help="busy processes to run meanwhile")
    ap.add_argument("--switch-only", action="store_true", help="only time the preset switch")
    ap.add_argument("--settings", default="wall:20,external:20,external:5", help="CLOCK:PERIOD_MS,...")
    a = ap.parse_args()
    settings = [(c, float(p)) for c, p in (s.split(":") for s in a.settings.split(","))]
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(max(0, a.load))]
    try:
        print(
            f"board clock, lock-stepped vehicle at --speed {a.speed:g}, {a.presets} presets alternating "
            f"{PRESETS[0]} / {PRESETS[1]} N*m (tolerance {TOLERANCE_NM} N*m), {a.load} busy processes, "
            f"load average {os.getloadavg()[0]:.1f}"
        )
        steps = switch_times()
        total = sum(t for _, t in steps[1:])
        print(
            "the pilot's angle-changing preset switch on the vehicle's clock, board s: "
            + "; ".join(f"{w} {t:.2f}" for w, t in steps[1:])
            + f"; switch total {total:.2f} (before it, {steps[0][0]}: {steps[0][1]:.2f})",
            flush=True,
        )
        if a.switch_only:
            return
        print(
            "clock     period    settle as the driver sees it, vehicle s | as the board reports it, board s"
            " | board - vehicle time over the run | vehicle x real time"
        )
        for clock, period in settings:
            r = run(clock, period, a.speed, a.presets)
            fmt = " ".join(f"{x:.2f}" for x in r["vehicle_s"])
            fmb = " ".join(f"{x:.2f}" for x in r["board_s"])
            print(
                f"{clock:9s} {period:4g} ms  median {statistics.median(r['vehicle_s']):.2f} ({fmt}) | "
                f"median {statistics.median(r['board_s']):.2f} ({fmb}) | {r['drift_s']:+.2f} s | "
                f"{r['vehicle_speed']:.2f}",
                flush=True,
            )
        print(f"load average at the end {os.getloadavg()[0]:.1f}")
    finally:
        for p in burners:
            p.kill()
            p.wait()


if __name__ == "__main__":
    main()
