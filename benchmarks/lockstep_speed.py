"""How fast a lock-stepped simulated landing runs: vehicle seconds per wall second for each phase
of one flight, flown straight to the vehicle and through the fault-injecting relay (no faults
set), in one run.

    python3 benchmarks/lockstep_speed.py [--speed 20] [--slope 30]

The vehicle (``--lockstep``) waits for the companion's TIMESYNC echo, so its speed is set by how
quickly the companion's loop and the link answer, up to ``--speed``. Two things held it back
(2026-11-23): the relay's TCP legs had Nagle's algorithm on (a small frame waited for the peer's
delayed ACK: about real time through the relay), and the landing loop's rate limit was in local
time (at most about five times real time in a landing).
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

from slopelander_sitl.rig import Rig  # noqa: E402


def fly(speed: float, slope: float, relay: bool) -> list[tuple[str, float, float]]:
    rows = []
    with Rig(slope_deg=slope, seed=3, speed=speed, relay=relay) as rig:

        def phase(name, fn):
            w, v = time.monotonic(), rig.now
            out = fn()
            rows.append((name, rig.now - v, time.monotonic() - w))
            return out

        phase("take-off", lambda: rig.take_off(3.0))
        phase("over the roof", lambda: rig.go_over_roof(2.5))
        flight = phase("landing", lambda: rig.land((1.2, 1.7)))
        rows.append((f"(ended {flight.end})", 0.0, 0.0))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", type=float, default=20.0)
    ap.add_argument("--slope", type=float, default=30.0)
    a = ap.parse_args()
    for relay in (False, True):
        print(f"{'through the relay' if relay else 'straight to the vehicle'} (--speed {a.speed:g}):")
        for name, vt, wall in fly(a.speed, a.slope, relay):
            if wall:
                print(f"  {name:14s} {vt:6.2f} s vehicle in {wall:5.2f} s wall: {vt / wall:5.2f}x real time")
            else:
                print(f"  {name}")


if __name__ == "__main__":
    main()
