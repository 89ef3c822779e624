"""The companion's CPU use while it descends: CPU time of the controller's process per second of
vehicle time, with HIGHRES_IMU and RAW_IMU streamed at 200 Hz (the full IMU rate) and the
rangefinder at 50 Hz. Goal: under 5 % of one core.

    python3 benchmarks/controller_cpu.py [--descents 3] [--speed 1]

Real processes: the simulated vehicle (real time by default, lock-step) and leg board; this
process is the companion: the MAVLink link, the leg driver and the landing state machine
(slopelander.controller.runner.Lander, polled as `slopelander land` polls it). Measured from
DESCEND to the cut (the descent from 2.8 m above a 20 deg roof, about 5 s each) with
``time.process_time()`` (user + system CPU of this process, all threads), against the vehicle
time that passed. At --speed 1 the vehicle runs in real time, so the per-second costs of the
controller's poll loop count as they would on the vehicle; faster speeds give less.
Streams: the two IMU messages, DISTANCE_SENSOR, HEARTBEAT, LOCAL_POSITION_NED (the rig flies the
vehicle over the roof with it), and what the simulated vehicle streams by default (ATTITUDE,
SERVO_OUTPUT_RAW, RC_CHANNELS); ``--telemetry`` adds what the flight tests record.

Each descent is flown twice in the same run, in turn: "before", the controller as it was until
2026-11-23 (every message decoded by pymavlink's own reader, ``Link(decode=None)``, and the loop
woken by every datagram, ``link.poll_period_s: 0``), and "after", as ``slopelander land`` runs now:
only the frames the landing reads are decoded (``decode=LANDING_MESSAGES``; the others, HIGHRES_IMU
among them, are dropped by message id first), the loop wakes at most every ``link.poll_period_s``
(``--poll-period`` to try another), and every RAW_IMU sample still reaches the impact detector.
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

from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from slopelander.controller.link import LANDING_MESSAGES  # noqa: E402
from slopelander.controller.runner import Lander  # noqa: E402
from slopelander_sitl.rig import Rig, config  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--descents", type=int, default=3)
    ap.add_argument("--speed", type=float, default=1.0)
    ap.add_argument(
        "--telemetry",
        action="store_true",
        help="also stream what the test rig records (position, attitude, outputs at 50 Hz, RC)",
    )
    ap.add_argument(
        "--poll-period",
        type=float,
        default=None,
        help="the 'after' loop's link.poll_period_s (default: the shipped setting)",
    )
    a = ap.parse_args()
    after_link = {} if a.poll_period is None else {"poll_period_s": a.poll_period}
    cfgs = {
        "before": config(reflex={"arm_height_m": 0.5}, link={"poll_period_s": 0.0}),
        "after": config(reflex={"arm_height_m": 0.5}, link=after_link),
    }
    with Rig(
        slope_deg=20.0,
        seed=5,
        speed=a.speed,
        imu_message=mavlink.MAVLINK_MSG_ID_HIGHRES_IMU,
        telemetry=a.telemetry,
    ) as rig:
        rig.wait_command(rig.link.request_stream(mavlink.MAVLINK_MSG_ID_RAW_IMU, 200), "RAW_IMU")
        # ATTITUDE at the rate `slopelander land` asks for (the simulated vehicle sends 50 Hz unasked)
        att_hz = cfgs["after"]["link.attitude_hz"]
        rig.wait_command(rig.link.request_stream(mavlink.MAVLINK_MSG_ID_ATTITUDE, att_hz), "ATTITUDE")
        rig.take_off(3.0)
        totals = {"before": [0.0, 0.0], "after": [0.0, 0.0]}
        for i in range(2 * a.descents):
            mode = "before" if i % 2 == 0 else "after"
            rig.link.set_decode(None if mode == "before" else LANDING_MESSAGES)
            cfg = cfgs[mode]
            rig.go_over_roof(2.8)
            rig.set_legs(1.7, 2.3)
            lander = Lander(rig.link, cfg, (1.7, 2.3), legs=rig.legs)
            assert lander.run(60.0, until=("DESCEND", "ABORTED")) == "DESCEND", lander.machine.history
            c0, t0, w0 = time.process_time(), rig.now, time.monotonic()
            end = lander.run(60.0, until=("CUT", "ABORTED", "LANDED"))
            if end != "CUT":
                print(lander.machine.history[-3:], flush=True)
            cpu, vt, wall = time.process_time() - c0, rig.now - t0, time.monotonic() - w0
            hz = {
                k: round(rig.link.rate_hz(k))
                for k in ("HIGHRES_IMU", "RAW_IMU", "DISTANCE_SENSOR", "ATTITUDE")
            }
            print(
                f"descent {i // 2 + 1} {mode:>6} (to {end}): {vt:.2f} s vehicle time ({wall:.2f} s wall), "
                f"CPU {cpu:.3f} s = {100 * cpu / vt:.2f} % of one core; decoded rates {hz} Hz",
                flush=True,
            )
            if end == "CUT":  # a descent cut short (a stalled machine's link loss) is not counted
                totals[mode][0] += cpu
                totals[mode][1] += vt
            lander.run(60.0)
            rig.wait(0.5)
            rig.take_off(rig.height() + 1.5, force=True)
    for mode, (cpu, vt) in totals.items():
        print(
            f"controller CPU while descending with HIGHRES_IMU + RAW_IMU at 200 Hz, {mode:>6}: "
            f"{100 * cpu / vt:.2f} % of one core over {vt:.1f} s of vehicle time "
            f"(--speed {a.speed:g}{', rig telemetry too' if a.telemetry else ''}; goal < 5 %)"
        )
    (c0, t0), (c1, t1) = totals.values()
    print(f"after / before: {(c1 / t1) / (c0 / t0):.2f}")


if __name__ == "__main__":
    main()
