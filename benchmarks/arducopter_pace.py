"""How long one landing on real ArduCopter SITL takes, and what CPU it costs, at real time and at
the rig's speed-up now that the physics holds ArduCopter for the companion
(src/slopelander_sitl/json_physics/companion_gate.py).

Each flight is the tests' pad-to-roof landing at 35 deg (tests/flights/
test_landings_on_both_autopilots.py: take-off, transit, the landing as `slopelander land` plans
it); it prints the wall time from the rig's ready to the end of the landing, the vehicle time it
covered, the CPU of every process (ArduCopter, physics, pod, leg board, this one; ArduCopter's
fast boot included) and what the physics' gate held, alternating the speed-ups ``--runs`` times
each. Needs SLOPELANDER_ARDUCOPTER (or --arducopter).

    python benchmarks/arducopter_pace.py [--runs 1] [--speedups 1 8]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from slopelander_sitl.proc_cpu import process_tree_cpu  # noqa: E402
from slopelander_sitl.rig import Rig, config  # noqa: E402
from tests.flights.test_landings_on_both_autopilots import FALL_M, contact_range  # noqa: E402

SLOPE_DEG = 35.0


def own_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def one(binary: str | None, speedup: float) -> dict:
    cfg = config(reflex={"cut_height_m": round(max(0.3, contact_range(SLOPE_DEG) + FALL_M), 2)})
    cpu0 = own_cpu()
    with Rig(
        slope_deg=SLOPE_DEG,
        seed=int(SLOPE_DEG) + 1,
        autopilot="ardupilot",
        arducopter=binary,
        arducopter_speedup=speedup,
    ) as rig:
        pod = rig.vehicle
        w0, v0 = time.monotonic(), rig.now
        p, _ = rig.plan(cfg)
        rig.take_off(3.0)
        rig.go_over_roof(2.5)
        flight = rig.land(
            (p.tau_up, p.tau_down), cfg, timeout_s=90.0, rest_s=3.0, uphill_angle_deg=p.angle_up_deg
        )
        wall, vehicle = time.monotonic() - w0, rig.now - v0
        cpu = process_tree_cpu(pod.proc.pid) + process_tree_cpu(rig.board.proc.pid)
    gate = pod.summary.split("echoes=", 1)[-1] if "echoes=" in pod.summary else "no gate"
    return {
        "end": flight.end,
        "wall": wall,
        "vehicle": vehicle,
        "cpu": cpu + own_cpu() - cpu0,
        "gate": "echoes=" + gate if gate != "no gate" else gate,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1, help="flights at each speed-up, alternated")
    ap.add_argument("--speedups", type=float, nargs="+", default=[1.0, 8.0])
    ap.add_argument("--arducopter", metavar="PATH", help="ArduCopter SITL binary (else the env var)")
    a = ap.parse_args()
    rows: dict[float, list[dict]] = {s: [] for s in a.speedups}
    for _ in range(a.runs):
        for s in a.speedups:
            r = one(a.arducopter, s)
            rows[s].append(r)
            print(
                f"  speed-up {s:g}: {r['end']}, {r['wall']:.1f} s wall for {r['vehicle']:.1f} s of "
                f"vehicle time ({r['vehicle'] / r['wall']:.2f}x), CPU {r['cpu']:.1f} s; gate {r['gate']}",
                flush=True,
            )
    med = {
        s: (statistics.median(r["wall"] for r in v), statistics.median(r["cpu"] for r in v))
        for s, v in rows.items()
    }
    base = a.speedups[0]
    print(
        "one 35 deg landing after the boot, median wall / CPU: "
        + "; ".join(
            f"speed-up {s:g}: {w:.1f} s ({med[base][0] / w:.2f}x faster than {base:g}) / {c:.1f} s"
            for s, (w, c) in med.items()
        )
        + f"; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
