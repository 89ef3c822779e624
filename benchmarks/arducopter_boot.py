"""How long real ArduCopter SITL takes from launch until it arms in GUIDED, and what CPU that
costs, booted at the flight's speed-up or with the fast boot (src/slopelander_sitl/ardupilot/fast_boot.py).

Each start launches ArduCopter on the JSON physics (pad, 35 deg roof) through
``start_arducopter``, connects the companion's link as the rig does, and arms in GUIDED as every
flight does (``slopelander_sitl.guided.arm_in_guided``); it prints the wall time to "ready" and to armed, the
vehicle time at arming, and the CPU of ArduCopter, its physics and its pod (/proc, before they
stop), alternating the two ways ``--runs`` times each, with the ratio in one run. Needs
SLOPELANDER_ARDUCOPTER (or --arducopter).

    python benchmarks/arducopter_boot.py [--runs 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from slopelander.controller.link import Link  # noqa: E402
from slopelander_sitl.ardupilot.launch import BOOT_SPEEDUP, start_arducopter  # noqa: E402
from slopelander_sitl.guided import arm_in_guided  # noqa: E402
from slopelander_sitl.proc_cpu import process_tree_cpu  # noqa: E402


def one(binary: str | None, fast: bool) -> tuple[float, float, float, float]:
    """(wall s to ready, wall s to armed, vehicle s at arming, CPU s) of one start."""
    t0 = time.monotonic()
    ap = start_arducopter(
        scenario={"slope_deg": 35.0, "roof_x": 3.0, "roof_z": 0.5},
        binary=binary,
        speedup=1.0,
        boot_speedup=BOOT_SPEEDUP if fast else None,
    )
    try:
        ready = time.monotonic() - t0
        link = Link(ap.mavlink_url)
        try:
            link.wait_autopilot(timeout_s=30.0)
            arm_in_guided(link, link.poll)
            armed = time.monotonic() - t0
            vehicle_s = link.clock.now()
        finally:
            link.close()
        cpu = process_tree_cpu(ap.proc.pid)
    finally:
        ap.stop()
    return ready, armed, vehicle_s, cpu


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2, help="starts each way, alternated")
    ap.add_argument("--arducopter", metavar="PATH", help="ArduCopter SITL binary (else the env var)")
    a = ap.parse_args()
    rows: dict[bool, list[tuple[float, float, float, float]]] = {False: [], True: []}
    for _ in range(a.runs):
        for fast in (False, True):
            rows[fast].append(one(a.arducopter, fast))
            r = rows[fast][-1]
            print(
                f"  {'fast boot' if fast else 'real time':9}: ready {r[0]:5.1f} s, armed {r[1]:5.1f} s "
                f"(vehicle {r[2]:5.1f} s), CPU {r[3]:5.1f} s",
                flush=True,
            )
    med = {k: [statistics.median(x[i] for x in v) for i in range(4)] for k, v in rows.items()}
    print(
        f"launch to armed in GUIDED, median of {a.runs}: real time {med[False][1]:.1f} s, fast boot "
        f"{med[True][1]:.1f} s ({med[False][1] / med[True][1]:.1f}x); CPU {med[False][3]:.1f} s vs "
        f"{med[True][3]:.1f} s; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
