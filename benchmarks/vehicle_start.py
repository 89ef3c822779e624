"""What starting a simulated vehicle and its leg board costs, fresh or forked from the forkserver.

A test run starts one vehicle and one leg board for every landing. Started fresh, each process
imports numba, pymavlink's dialect and lupa and loads the compiled model from numba's cache
before its first tick; forked from the multiprocessing forkserver that preloads ``slopelander_sitl.warm``
(``src/slopelander_sitl/processes.py``, which the test suite uses), it starts from a process that did this
once.
Prints, for ``--starts`` vehicle + leg-board pairs each way, the wall time until both said
"ready" and their CPU time until then (read from /proc while they run), the forkserver's own
one-off CPU, and the ratio, in one run.

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

import multiprocessing.forkserver  # noqa: E402

from slopelander_sitl import processes  # noqa: E402
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
    processes.use_forkserver()
    multiprocessing.forkserver.ensure_running()  # returns at once: the preload runs in the server
    server = multiprocessing.forkserver._forkserver._forkserver_pid
    first = one_pair()  # waits for the preload
    zy_cpu = cpu_seconds(server)
    forked = [one_pair() for _ in range(a.starts)]

    def row(name: str, runs: list[tuple[float, float]]) -> tuple[float, float]:
        w = statistics.median(r[0] for r in runs)
        c = statistics.median(r[1] for r in runs)
        print(f"  {name:28s} wall to ready {w:5.2f} s (median)   CPU to ready {c:5.2f} s (median)")
        return w, c

    fw, fc = row("fresh processes", fresh)
    zw, zc = row("forked from the forkserver", forked)
    print(f"  the forkserver's own start (once): CPU {zy_cpu:.2f} s; the first pair then: {first[0]:.2f} s")
    print(f"ratio fresh / forked: wall {fw / zw:.1f}x, CPU {fc / zc:.1f}x ({load()})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
