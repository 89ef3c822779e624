"""Landing latencies over many landings, in the vehicle's own time: the on-board reflex's
rangefinder cut -> motors stopped and contact -> reverse-thrust outputs, the companion's contact
-> impact detected (in the streamed RAW_IMU at 200 Hz), and the cut's height error. Prints median
and p99 of each.

    python3 benchmarks/landing_latency.py [--landings 100] [--slopes 15,25,35] [--seed 1]
        [--autopilot sim|ardupilot] [--arducopter PATH] [--speedup 4] [--save FILE.jsonl]

``--autopilot ardupilot`` flies real ArduCopter SITL (``--arducopter PATH`` or
``SLOPELANDER_ARDUCOPTER``) behind the same physics, whose events (EV_CONTACT, EV_STOP, EV_RVT)
reach the rig from a file; a landing there ends when ArduCopter's HEARTBEAT shows it disarmed.
ArduCopter is lock-stepped with the physics, not with the companion or the leg board: at its
``--speedup`` (default 4) a loaded machine can leave them behind; 1 keeps it to real time.
``--save`` writes each landing's figures as a JSON line as it is flown (``benchmarks/cut_height.py
FILE`` summarises them). The cut's own figures are printed too (benchmarks/cut_height.py): the
range when the motors stopped against the cut height, and contact after the stop.

Real processes (the simulated vehicle in lock-step with the companion): the simulated vehicle (or
ArduCopter) with the on-board script, the leg board, the companion's controller
(slopelander.controller.runner.Lander). Between landings the vehicle takes off again from the roof
by the controller's own take-off (TAKEOFF -> RESET -> READY: the script releases the motors it
holds, the legs are loosened; the next landing sets its preset again), so a landing costs about 20
s of vehicle time. The cut height varies per landing (0.1-0.3 m of free fall: impact 1.1-2.5 m/s);
one vehicle per slope, each with its own noise seed.

Where each time comes from (src/slopelander_sitl/vehicle/events.py; all vehicle time):
- rangefinder cut: the first DISTANCE_SENSOR reading (stream at 200 Hz, cm) at or below the cut
  height. Both autopilots sample the rangefinder at 20 Hz and the script cuts on the second
  distinct sample at or below the cut (slopelander.lua, CUT_SAMPLES), so this is at least one
  sample period (50 ms); the true crossing lies up to 50 ms before the first such reading;
- motors stopped: EV_STOP, the first frame whose four outputs are all in the ESC stop band;
- contact: EV_CONTACT, the physics step (1/1200 s) of first contact;
- reflex reverse thrust: EV_RVT, the first frame whose four outputs all command reverse;
- companion, impact detected: the RAW_IMU sample that tripped the companion's detector
  (controller/impact.py), minus contact. The companion no longer commands the reverse itself
  (script v4 refuses an actuator command while a landing holds the motors: the reflex owns it),
  so there is no companion-commanded reverse to time;
- cut height error: benchmarks/cut_height.py (the rangefinder's readings before EV_STOP, fitted
  and read at EV_STOP, minus the cut height).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

import numpy as np  # noqa: E402

from benchmarks.cut_height import cut_figures, stats_line  # noqa: E402
from slopelander.controller.landing import leg_geometry  # noqa: E402
from slopelander.controller.runner import ENDINGS, Lander  # noqa: E402
from slopelander.controller.table import DEFAULT_TABLE, LookupTable  # noqa: E402
from slopelander.legs.errors import LegBoardError  # noqa: E402
from slopelander_sitl.rig import Rig, RigError, add_autopilot_args, config  # noqa: E402


def contact_range(slope_deg: float) -> float:
    g = leg_geometry()
    a = math.radians(g.leg_angle_deg)
    return g.leg_length_m * math.cos(a) + (g.joint_x_m + g.leg_length_m * math.sin(a)) * math.tan(
        math.radians(slope_deg)
    )


def one_landing(rig: Rig, fall_m: float, table: LookupTable) -> tuple[dict, Lander]:
    """Fly one landing; return the latencies it showed (s) and its controller."""
    cut = round(contact_range(rig.slope_deg) + 0.03 + fall_m, 2)
    cfg = config(reflex={"cut_height_m": cut})
    v = math.sqrt(0.25 + 2 * 9.80665 * fall_m)
    p = table.lookup(rig.slope_deg, v)
    lander = Lander(rig.link, cfg, (p.tau_up, p.tau_down), legs=rig.legs)
    t0 = rig.now
    seen = None
    end = time.monotonic() + (120 if rig.autopilot == "ardupilot" else 60)
    while time.monotonic() < end:
        name = lander.poll()
        imp = lander.detector.impact
        if imp is not None and seen is None:
            seen = imp.t
        if lander.machine._started and name in ENDINGS:
            break
        time.sleep(0.001)
    out: dict = {"end": name, "cut": cut, "autopilot": rig.autopilot, "armed_after": rig.armed()}
    out["history"] = [(round(h["t"], 3), h["to"], h["reason"]) for h in lander.machine.history]
    if name != "LANDED" and lander.machine.history:
        out["why"] = lander.machine.history[-1]["reason"]
    if rig.autopilot == "ardupilot":  # the firmware's own words (the script's too), for the findings
        out["statustext"] = rig.vehicle.statustexts()[-30:]
    rig.read_events()
    tr = rig.track
    out.update(cut_figures(tr, t0, cut))
    c = tr.contact(t0)
    stop = tr.event_times("EV_STOP", t0)
    if c is None or not stop:
        return out, lander
    out["vz"] = c["vz"]
    below = [t for t, r in tr.ranges if t > t0 and r <= cut]
    if below and stop[0] < c["t"]:  # a free fall: the cut came before contact
        out["cut_to_stop"] = stop[0] - below[0]
    rvt = tr.event_times("EV_RVT", c["t"] - 0.001)
    if rvt:
        out["impact_to_rvt"] = rvt[0] - c["t"]
    if seen is not None:
        out["detect"] = seen - c["t"]
    return out, lander


def again(rig: Rig, lander: Lander) -> None:
    """Up again from the roof by the controller's own take-off (TAKEOFF -> RESET -> READY: the
    script releases the motors it holds, the legs are loosened) and over the landing spot. A
    landing that did not end LANDED cannot take off this way: a fresh vehicle goes on."""
    if lander.machine.name != "LANDED":
        raise RigError(f"no take-off from the roof after {lander.machine.name}")
    lander.takeoff_request = True
    end = lander.run(90.0, until=("READY", "ABORTED", "ESTOP"))
    if end != "READY":
        why = lander.machine.history[-1]["reason"] if lander.machine.history else ""
        raise RigError(f"take-off from the roof ended {end} ({why})")
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
    add_autopilot_args(ap)
    ap.add_argument("--save", metavar="FILE", help="write each landing's figures as a JSON line")
    a = ap.parse_args()
    if a.autopilot == "ardupilot":
        from slopelander_sitl.ardupilot.launch import ArduCopterMissingError, arducopter_binary

        try:
            arducopter_binary(a.arducopter)
        except ArduCopterMissingError as exc:
            sys.exit(f"landing_latency: {exc}")
    if a.save:
        open(a.save, "w").close()
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
            fly_slope(slope, a.seed * 100 + i + 10 * failures, todo, rows, rng, table, a)
        except (RigError, LegBoardError) as exc:  # the vehicle could not be brought back: a fresh one goes on
            failures += 1
            print(f"{slope:4.0f} deg: {exc}; starting a new vehicle", flush=True)
            if failures > 5:
                raise
    print(
        f"{len(rows)} landings on {a.slopes} deg in {time.monotonic() - wall0:.0f} s wall, "
        f"{failures} vehicle restarts, on {a.autopilot}; "
        f"{sum(1 for r in rows if r['end'] == 'LANDED' and not r['armed_after'])} ended LANDED and disarmed"
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
        stats_line(
            "cut height error, range at motors stopped - cut",
            [r["cut_error"] for r in rows if "cut_error" in r],
            "cm",
            100.0,
        )
    )
    print(
        stats(
            "motors stopped -> contact", [r["contact_after_stop"] for r in rows if "contact_after_stop" in r]
        )
    )


def fly_slope(slope, seed, todo, rows, rng, table, a) -> None:
    """Land on one vehicle as long as the next landings in ``todo`` are on its slope."""
    with Rig(
        slope_deg=slope,
        seed=seed,
        range_hz=200.0,
        autopilot=a.autopilot,
        arducopter=a.arducopter,
        arducopter_speedup=a.speedup,
    ) as rig:
        rig.take_off(3.0)
        rig.go_over_roof(1.8)
        while todo and todo[0][1] == slope:
            r, lander = one_landing(rig, float(rng.uniform(0.1, 0.3)), table)
            r["slope"] = slope
            rows.append(r)
            todo.pop(0)
            if a.save:  # as it is flown: a run stopped early keeps what it flew
                with open(a.save, "a") as fh:
                    fh.write(json.dumps(r, default=float) + "\n")
            shown = " ".join(
                f"{k} {1000 * r[k]:.1f}"
                for k in ("cut_to_stop", "impact_to_rvt", "detect", "contact_after_stop")
                if k in r
            )
            if "cut_error" in r:
                shown += f" ms, cut error {100 * r['cut_error']:+.1f} cm"
            else:
                shown += " ms"
            print(
                f"{slope:4.0f} deg cut {r['cut']:.2f} m: {r['end']:<8} "
                f"impact {r.get('vz', math.nan):.2f} m/s {shown}" + (f" ({r['why']})" if "why" in r else ""),
                flush=True,
            )
            if todo and todo[0][1] == slope:
                again(rig, lander)


if __name__ == "__main__":
    main()
