"""Landing latencies over many simulated landings, in the vehicle's own time: the on-board
reflex's rangefinder cut -> motors stopped and impact -> reverse-thrust outputs, and the
companion path's contact -> reverse thrust (impact seen in the streamed RAW_IMU at 200 Hz,
MAV_CMD_USER_1 reverse sent, the script acting on it). Prints median and p99 of each.

    python3 benchmarks/landing_latency.py [--landings 100] [--slopes 15,25,35] [--seed 1]

Real processes in lock-step: the simulated vehicle with the on-board script, the leg board, the
companion's controller (slopelander.controller.runner.Lander). Between landings the vehicle takes
off again from the roof without loosening the legs (the preset stays set), so a landing costs
about 10 s of vehicle time. The cut height varies per landing (0.1-0.3 m of free fall: impact
1.1-2.5 m/s); one vehicle per slope, each with its own noise seed.

Where each time comes from (sitl/vehicle/events.py; all vehicle time):
- rangefinder cut: the first DISTANCE_SENSOR sample (stream at 200 Hz, cm) at or below the cut
  height; the true crossing lies up to 5 ms before it, so this figure is low by up to 5 ms;
- motors stopped: EV_STOP, the control tick whose four outputs are all in the ESC stop band;
- contact: EV_CONTACT, the physics step (1/1200 s) of first contact;
- reflex reverse thrust: EV_RVT, the control tick whose four outputs all command reverse;
- companion reverse thrust: the SL_STATE report of the script entering REVERSE (2) on the
  companion's command, stamped in whole ms by the script's update that set the outputs. The
  companion sends it when its detector (controller/impact.py) trips; the reflex has already
  reversed by then, the command only takes over. Its detection part (contact -> the RAW_IMU
  sample that tripped the detector) is printed on its own: it does not depend on lock-step.
  The rest (the link, the companion's loop) is measured under lock-step, where the vehicle may
  run up to 50 ms of its time ahead of the companion: an upper bound for a real-time link.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

import numpy as np  # noqa: E402

from sitl.rig import Rig, RigError, config  # noqa: E402
from slopelander.controller.landing import leg_geometry  # noqa: E402
from slopelander.controller.runner import ENDINGS, Lander  # noqa: E402
from slopelander.controller.table import DEFAULT_TABLE, LookupTable  # noqa: E402

SCRIPT_REVERSE = 2


def contact_range(slope_deg: float) -> float:
    g = leg_geometry()
    a = math.radians(g.leg_angle_deg)
    return g.leg_length_m * math.cos(a) + (g.joint_x_m + g.leg_length_m * math.sin(a)) * math.tan(
        math.radians(slope_deg)
    )


def one_landing(rig: Rig, fall_m: float, table: LookupTable) -> dict[str, float]:
    """Fly one landing with the companion path armed; return the latencies it showed (s)."""
    cut = round(contact_range(rig.slope_deg) + 0.03 + fall_m, 2)
    cfg = config(reflex={"cut_height_m": cut})
    v = math.sqrt(0.25 + 2 * 9.80665 * fall_m)
    p = table.lookup(rig.slope_deg, v)
    lander = Lander(rig.link, cfg, (p.tau_up, p.tau_down), legs=rig.legs)
    t0 = rig.now
    sent = None
    end = time.monotonic() + 60
    while time.monotonic() < end:
        name = lander.poll()
        imp = lander.detector.impact
        if imp is not None and sent is None:
            lander.act.reverse(cfg["reflex.reverse_thrust_pct"], int(cfg["reflex.reverse_thrust_ms"]))
            sent = (imp.t, rig.now)
        if lander.machine._started and name in ENDINGS:
            break
        time.sleep(0.001)
    out: dict[str, float] = {"end": name, "cut": cut}
    if name != "LANDED" and lander.machine.history:
        out["why"] = lander.machine.history[-1]["reason"]
    tr = rig.track
    c = tr.contact(t0)
    stop = tr.event_times("EV_STOP", t0)
    if c is None or not stop:
        return out
    out["vz"] = c["vz"]
    below = [t for t, r in tr.ranges if t > t0 and r <= cut]
    if below and stop[0] < c["t"]:  # a free fall: the cut came before contact
        out["cut_to_stop"] = stop[0] - below[0]
    rvt = tr.event_times("EV_RVT", c["t"] - 0.001)
    if rvt:
        out["impact_to_rvt"] = rvt[0] - c["t"]
    if sent is not None:
        out["detect"] = sent[0] - c["t"]
        rev = [t for t, s in tr.script if s == SCRIPT_REVERSE and t > c["t"]]
        if rev:
            out["companion"] = rev[0] - c["t"]
    return out


def again(rig: Rig, lander_end: str) -> None:
    """Up again from the roof (legs left as they are) and over the landing spot."""
    rig.wait(0.2)
    rig.take_off(max(rig.height() + 1.5, 0.3), force=True)  # NAV_TAKEOFF: metres above home, > 0
    rig.go_over_roof(1.8)


def stats(name: str, xs: list[float]) -> str:
    if not xs:
        return f"{name}: no samples"
    a = np.array(xs) * 1000.0
    return (
        f"{name}: median {np.median(a):.1f} ms, p99 {np.percentile(a, 99):.1f} ms "
        f"(min {a.min():.1f}, max {a.max():.1f}, n={len(a)})"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--landings", type=int, default=100)
    ap.add_argument("--slopes", default="15,25,35")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    slopes = [float(s) for s in a.slopes.split(",")]
    rng = np.random.default_rng(a.seed)
    table = LookupTable.load(DEFAULT_TABLE)
    rows: list[dict[str, float]] = []
    wall0 = time.monotonic()
    per = [a.landings // len(slopes) + (1 if i < a.landings % len(slopes) else 0) for i in range(len(slopes))]
    failures = 0
    todo = [(i, slope) for i, (slope, n) in enumerate(zip(slopes, per, strict=True)) for _ in range(n)]
    while todo:
        i, slope = todo[0]
        try:
            fly_slope(slope, a.seed * 100 + i + 10 * failures, todo, rows, rng, table)
        except RigError as exc:  # the vehicle could not be brought back: a fresh one goes on
            failures += 1
            print(f"{slope:4.0f} deg: {exc}; starting a new vehicle", flush=True)
            if failures > 5:
                raise
    print(
        f"{len(rows)} landings on {a.slopes} deg in {time.monotonic() - wall0:.0f} s wall, "
        f"{failures} vehicle restarts"
    )
    print(
        stats(
            "on-board reflex, rangefinder cut -> motors stopped",
            [r["cut_to_stop"] for r in rows if "cut_to_stop" in r],
        )
    )
    print(
        stats(
            "on-board reflex, contact -> reverse-thrust outputs",
            [r["impact_to_rvt"] for r in rows if "impact_to_rvt" in r],
        )
    )
    print(
        stats(
            "companion, contact -> impact detected in RAW_IMU", [r["detect"] for r in rows if "detect" in r]
        )
    )
    print(
        stats(
            "companion, contact -> script reverses on its command",
            [r["companion"] for r in rows if "companion" in r],
        )
    )


def fly_slope(slope, seed, todo, rows, rng, table) -> None:
    """Land on one vehicle as long as the next landings in ``todo`` are on its slope."""
    with Rig(slope_deg=slope, seed=seed, range_hz=200.0) as rig:
        rig.take_off(3.0)
        rig.go_over_roof(1.8)
        while todo and todo[0][1] == slope:
            r = one_landing(rig, float(rng.uniform(0.1, 0.3)), table)
            r["slope"] = slope
            rows.append(r)
            todo.pop(0)
            shown = " ".join(
                f"{k} {1000 * r[k]:.1f}"
                for k in ("cut_to_stop", "impact_to_rvt", "detect", "companion")
                if k in r
            )
            print(
                f"{slope:4.0f} deg cut {r['cut']:.2f} m: {r['end']:<8} "
                f"impact {r.get('vz', math.nan):.2f} m/s {shown} ms"
                + (f" ({r['why']})" if "why" in r else ""),
                flush=True,
            )
            if todo and todo[0][1] == slope:
                again(rig, r["end"])


if __name__ == "__main__":
    main()
