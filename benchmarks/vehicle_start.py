"""What starting a simulated vehicle and its leg board costs, fresh or forked from the zygote.

A test run starts one vehicle and one leg board for every landing. Started fresh, each process
imports numba, pymavlink's dialect and lupa and loads the compiled model from numba's cache
before its first tick; forked from the zygote (``src/slopelander_sitl/zygote.py``, which the test suite uses),
it starts from a process that did this once. Prints, for ``--starts`` vehicle + leg-board pairs
each way, the wall time until both said "ready" and their CPU time until then (read from
/proc while they run), the zygote's own one-off CPU, and the ratio, in one run.

    python benchmarks/vehicle_start.py [--starts 5]
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

from slopelander_sitl import zygote  # noqa: E402
from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User + system CPU of a running process, from /proc/PID/stat."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def one_pair() -> tuple[float, float]:
    t0 = time.perf_counter()
    board = start_legboard(clock="external")
    vehicle = start_vehicle(speed=1.0, lockstep=True, legboard_control=board.control)
    wall = time.perf_counter() - t0
    cpu = cpu_seconds(vehicle.proc.pid) + cpu_seconds(board.proc.pid)
    vehicle.stop()
    board.stop()
    return wall, cpu


def load() -> str:
    return "load average {:.1f} / {:.1f} / {:.1f}".format(*os.getloadavg())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=5)
    a = ap.parse_args()
    now = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    print(f"{now}: {a.starts} vehicle + leg board starts each way, {load()}")
    one_pair()  # numba's cache warm, files in the page cache: neither way pays a first time
    fresh = [one_pair() for _ in range(a.starts)]
    zygote.enable()
    z = zygote.active()
    assert z is not None
    t0 = time.perf_counter()
    z._ensure()
    zy_wall = time.perf_counter() - t0
    zy_cpu = cpu_seconds(z._proc.pid)
    forked = [one_pair() for _ in range(a.starts)]
    z.close()

    def row(name: str, runs: list[tuple[float, float]]) -> tuple[float, float]:
        w = statistics.median(r[0] for r in runs)
        c = statistics.median(r[1] for r in runs)
        print(f"  {name:28s} wall to ready {w:5.2f} s (median)   CPU to ready {c:5.2f} s (median)")
        return w, c

    fw, fc = row("fresh processes", fresh)
    zw, zc = row("forked from the zygote", forked)
    print(f"  the zygote's own start (once): wall {zy_wall:.2f} s, CPU {zy_cpu:.2f} s")
    print(f"ratio fresh / forked: wall {fw / zw:.1f}x, CPU {fc / zc:.1f}x ({load()})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
