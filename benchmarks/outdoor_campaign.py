"""The paper's outdoor campaign re-flown in simulation: 25 landings on 25-45 deg roofs at
1.5-3 m/s, by the companion's controller against the simulated vehicle and leg board (real
processes, lock-step). Prints the outcome table and how many landed (paper: 25/25).

    python3 benchmarks/outdoor_campaign.py [--landings 25] [--seed 7] [--autopilot sim|ardupilot]

``--autopilot ardupilot`` flies real ArduCopter SITL (``--arducopter PATH`` or
``SLOPELANDER_ARDUCOPTER``) behind the same physics, one boot per landing; the landing ends when
its HEARTBEAT shows it disarmed (the controller's LANDED). The simulated vehicle's own judge
(last column) does not exist there. Per landing it also prints the cut's figures
(benchmarks/cut_height.py): the range when the motors stopped against the cut height, contact
after the stop, contact -> reverse-thrust outputs; their medians and p99 at the end. ``--only
4,7`` flies only those landings (the same draws), e.g. the ones a loaded machine kept the rig
from flying.

Each landing draws (from the seed):
- a roof slope s in 25..45 deg and a heading error h in -10..10 deg. The model is planar, so the
  vehicle flies over the slope as seen along its heading, atan(tan s * cos h);
- an impact speed in 1.5..3 m/s: the cut height is chosen for it (descent 0.5 m/s, free fall
  from the cut to the uphill foot's contact; the foot meets the roof about 6 cm above the range
  of the geometry in controller/landing.py, measured in the flight tests, so that is added);
- a horizontal speed in -0.4..0.4 m/s (+ = downhill), flown during the descent; the vehicle
  reaches it, but loses most of it between the cut and contact (measured: -0.35 m/s in the
  descent, -0.10 m/s at contact), so the table prints the horizontal speed at contact as flown;
- the legs: the lookup table's preset (torques and leg angles) for the planar slope and the impact
  speed, but in about 4 of 10 landings the preset of a neighbouring table cell (5 deg or 0.5 m/s
  off), not the best. The angles are set on the board (SET_ANGLE) before the landing, as the
  paper's legs were set by hand; ``--no-angles`` flies every leg at 37.5 deg instead.
Gusts: each landing's scenario draws ``--gusts`` random 1-cos gusts (1.5 s long, horizontal peak
up to ``--gust-n`` newtons either way, about 15 % of the vehicle's weight by default) over its
first 80 s of vehicle time, from the landing's seed (docs/simulated-vehicle.md, ``wind:``);
``--gusts 0`` flies calm air.

Outcome from the telemetry after contact until 2 s after the controller called the landing done,
with the model's criteria (src/slopelander_sitl/rig.py Flight.classify): slid = more than 1 m along the
roof or
still moving; flipped = pitch past 80 deg. Beside it: what the table said of the cell, and the
model's outcome for the contact state the vehicle reported (slope, speeds, pitch, rate, preset,
leg angles, reverse delay) with the reverse thrust as flown: held until the companion ended it,
then ramped down as the on-board script did (src/slopelander_sitl/rig.py Flight.model_conditions), and judged
after it; and, as the maps and the table assume, with the thrust held to the model's horizon.
Last, the simulated vehicle's own judge of the landing (its STATUSTEXT "Landing: ..."): the
model's classifier on the vehicle's physics, decided like the held column (at rest under the
thrust); it names a joint touch, which the telemetry's classes (landed/slid/flipped) cannot see.
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
from slopelander.controller.actions import DESCENT_TYPE_MASK  # noqa: E402
from slopelander.controller.landing import leg_geometry  # noqa: E402
from slopelander.controller.link import mavlink  # noqa: E402
from slopelander.controller.runner import Lander  # noqa: E402
from slopelander.controller.table import DEFAULT_TABLE, LookupTable  # noqa: E402
from slopelander.legs.errors import LegBoardError  # noqa: E402
from slopelander.model.landing import simulate  # noqa: E402
from slopelander_sitl.rig import Rig, RigError, add_autopilot_args, config  # noqa: E402

CONTACT_OFFSET_M = 0.06


def contact_range(slope_deg: float) -> float:
    g = leg_geometry()
    a = math.radians(g.leg_angle_deg)
    return g.leg_length_m * math.cos(a) + (g.joint_x_m + g.leg_length_m * math.sin(a)) * math.tan(
        math.radians(slope_deg)
    )


def model_class(conditions) -> tuple[str, float]:
    """The model's outcome for ``conditions`` in the flight's classes (landed / slid / flipped),
    and its slide along the roof (m)."""
    r = simulate(conditions).result
    m = r.outcome
    return "landed" if m.success else {"FLIP": "flipped", "SLID": "slid"}.get(m.name, m.name.lower()), r.slide


def landing_numbers(text: str) -> set[int]:
    """``--only``'s value: landing numbers (from 1), comma-separated."""
    try:
        out = {int(n) for n in text.split(",")}
    except ValueError:
        raise argparse.ArgumentTypeError(f"landing numbers, comma-separated (e.g. 4,7): {text!r}") from None
    if min(out) < 1:
        raise argparse.ArgumentTypeError("landings are numbered from 1")
    return out


def drifting(lander: Lander, vx: float) -> None:
    """The descent setpoint with a horizontal speed ``vx`` (m/s, + downhill) as well."""
    act = lander.act

    def descend(rate_mps: float) -> None:
        now = act.link.monotonic()
        if now - act._last_descent < 1.0 / act.cfg["descent.resend_hz"]:
            return
        act._last_descent = now
        info = act.link.info
        act.link.conn.mav.set_position_target_local_ned_send(
            int(act.link.clock.now() * 1000) & 0xFFFFFFFF, info.system, info.component,
            mavlink.MAV_FRAME_LOCAL_NED, DESCENT_TYPE_MASK, 0, 0, 0, vx, 0, float(rate_mps), 0, 0, 0, 0, 0,
        )  # fmt: skip

    act.descend = descend


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--landings", type=int, default=25)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--gusts", type=int, default=8, help="random gusts per landing (0: calm air)")
    ap.add_argument("--gust-n", type=float, default=2.0, help="largest gust force, either way (N)")
    ap.add_argument(
        "--no-angles",
        action="store_true",
        help="leave the legs at 37.5 deg instead of setting the table's angles on the board",
    )
    ap.add_argument(
        "--save-conditions",
        metavar="FILE",
        help="write each landing as a JSON line as it is flown: its draws, outcomes, model conditions "
        "(thrust as flown), the cut's figures and their evidence (benchmarks/cut_height.py reads it)",
    )
    add_autopilot_args(ap)
    ap.add_argument(
        "--only",
        type=landing_numbers,
        metavar="N,N",
        help="fly only these landings (1-based), e.g. to re-fly those the rig could not fly",
    )
    a = ap.parse_args()
    if a.autopilot == "ardupilot":
        from slopelander_sitl.ardupilot.launch import ArduCopterMissingError, arducopter_binary

        try:
            arducopter_binary(a.arducopter)
        except ArduCopterMissingError as exc:
            sys.exit(f"outdoor_campaign: {exc}")
    real, ap_name = a.autopilot == "ardupilot", a.autopilot
    rng = np.random.default_rng(a.seed)
    table = LookupTable.load(DEFAULT_TABLE)
    rows = []
    if a.save_conditions:
        open(a.save_conditions, "w").close()
    wall0 = time.monotonic()
    for i in range(a.landings):
        s, h = rng.uniform(25, 45), rng.uniform(-10, 10)
        planar = math.degrees(math.atan(math.tan(math.radians(s)) * math.cos(math.radians(h))))
        v, vx = rng.uniform(1.5, 3.0), rng.uniform(-0.4, 0.4)
        best = table.lookup(planar, v)
        if rng.uniform() < 0.4:
            ds, dv = [(-5, 0), (5, 0), (0, -0.5), (0, 0.5)][rng.integers(4)]
            p = table.lookup(min(60.0, max(0.0, planar + ds)), min(3.0, max(0.5, v + dv)))
            which = f"other: cell {p.cell}, best {best.cell}"
        else:
            p, which = best, f"cell {best.cell} best"
        fall = (v * v - 0.25) / (2 * 9.80665)
        cut = round(contact_range(planar) + CONTACT_OFFSET_M + fall, 2)
        cfg = config(reflex={"cut_height_m": cut})
        if a.only and i + 1 not in a.only:  # drawn all the same: landing N is the same landing
            continue
        row = {"landing": i + 1, "slope": s, "heading": h, "planar": planar, "v_goal": v, "vx_goal": vx,
               "autopilot": ap_name, "preset": (p.tau_up, p.tau_down), "which": which, "cut": cut,
               "table": p.outcome}  # fmt: skip
        try:
            wind = {"random_gusts": {"count": a.gusts, "max_n": a.gust_n, "from_s": 0.0, "to_s": 80.0,
                                     "duration_s": 1.5}} if a.gusts else {}  # fmt: skip
            scenario = {"wind": wind} if wind else None
            with Rig(slope_deg=round(planar, 2), seed=a.seed * 1000 + i, scenario=scenario, range_hz=100.0,
                     autopilot=a.autopilot, arducopter=a.arducopter,
                     arducopter_speedup=a.speedup) as rig:  # fmt: skip
                rig.take_off(3.0)
                rig.go_over_roof(2.0)
                if not a.no_angles:  # by hand before flight on the paper's legs; the board has ANGLE_STOP
                    op = rig.legs.start_angles({0: p.angle_up_deg, 1: p.angle_up_deg, 2: p.angle_down_deg,
                                                3: p.angle_down_deg})  # fmt: skip
                    rig.fly_until(lambda op=op: op.done, 30.0, "set the leg angles")
                # the landing's slope, as `slopelander land --slope` gives it
                lander = Lander(rig.link, cfg, (p.tau_up, p.tau_down), legs=rig.legs,
                                slope_deg=round(planar, 2))  # fmt: skip
                drifting(lander, vx)
                f = rig.land((p.tau_up, p.tau_down), cfg, lander=lander, timeout_s=90.0 if real else 60.0,
                             rest_s=2.0)  # fmt: skip
                row.update(cut_figures(rig.track, f.t_start, cut))
                row["armed_after"] = rig.armed()
                if real:  # the firmware's own words (the script's too), for the findings
                    row["statustext"] = rig.vehicle.statustexts()[-40:]
                c = f.contact
                outcome, fig = f.classify(planar)
                if c and a.save_conditions:
                    row["conditions"] = f.model_conditions().as_file_dict()  # no reverse_duration: held
                (model, m_slide), (held, _) = (
                    model_class(f.model_conditions(t)) if c else ("-", math.nan) for t in ("flown", "held")
                )
                # the simulated vehicle's own judge (the model's classifier on its physics, decided
                # as `simulate` decides a held thrust): it sees a joint touch, the telemetry does not
                said = [t.split()[1] for t in rig.track.statustext if t.startswith("Landing: ")]
                judge = said[-1] if said else "-"
                why = f.history[-1]["reason"] if f.history else ""
                row["history"] = [(round(x["t"], 3), x["to"], x["reason"]) for x in f.history]
                row.update(end=f.end, why=why, outcome=outcome, vz=c["vz"] if c else math.nan,
                           vx=c["vx"] if c else math.nan, slide=fig.get("slide_m", math.nan),
                           model=model, held=held, m_slide=m_slide, judge=judge)  # fmt: skip
        except (RigError, LegBoardError) as exc:  # the rig could not fly it: reported, not hidden
            row.update(end="rig error", why=str(exc), outcome="rig error", vz=math.nan, vx=math.nan,
                       slide=math.nan, model="-", held="-", m_slide=math.nan, judge="-")  # fmt: skip
        rows.append(row)
        if a.save_conditions:  # a line per landing as it is flown: a run stopped early keeps what it flew
            with open(a.save_conditions, "a") as fh:
                fh.write(json.dumps(row, default=float) + "\n")
        cutf = " ".join(f"{k} {row[k] * sc:.1f}{u}" for k, sc, u in (
            ("cut_error", 100, "cm"), ("contact_after_stop", 1000, "ms"), ("impact_to_rvt", 1000, "ms"))
            if k in row)  # fmt: skip
        print(
            f"{i + 1:2d}  roof {s:4.1f} deg, heading {h:+5.1f} -> {planar:4.1f} deg  "
            f"impact {row['vz']:4.2f} m/s "
            f"(goal {v:4.2f}), vx {row['vx']:+5.2f} (goal {vx:+5.2f})  legs {p.tau_up:.2f}/{p.tau_down:.2f} "
            f"{which}  cut {cut:.2f} m  {row['end']:<8} {row['outcome']}  slide {row['slide']:.2f} m"
            f"  model {row['model']}, slide {row['m_slide']:.2f} m"
            f"  ({row['why']})  {cutf}",
            flush=True,
        )
    landed = sum(1 for r in rows if r["outcome"] == "landed")
    print(f"\nlegs at {'37.5 deg' if a.no_angles else 'the table angles'}")
    print(
        f"{'slope':>6} {'planar':>6} {'speed':>6} {'vx':>6}  preset       table says    flown     "
        f"model       thrust held vehicle's judge  end"
    )
    for r in rows:
        print(
            f"{r['slope']:6.1f} {r['planar']:6.1f} {r['vz']:6.2f} {r['vx']:+6.2f}  "
            f"{r['preset'][0]:.2f}/{r['preset'][1]:.2f} {r['which'].split(':')[0].split()[-1]:<6}  "
            f"{r['table']:<13} {r['outcome']:<9} {r['model']:<11} {r['held']:<11} {r['judge']:<16} {r['end']}"
        )
    ended = sum(1 for r in rows if r["end"] == "LANDED" and not r.get("armed_after", True))
    agree = sum(1 for r in rows if r["outcome"] == r["model"])
    agree_held = sum(1 for r in rows if r["outcome"] == r["held"])
    print(
        f"on {a.autopilot}: landed {landed}/{len(rows)} (paper: 25/25), {ended} of them ended LANDED and "
        f"disarmed; the model, run for each contact state, agrees on "
        f"{agree}/{len(rows)} with the thrust as flown, {agree_held}/{len(rows)} with it held; "
        f"gusts: {a.gusts} per landing up to {a.gust_n} N; {time.monotonic() - wall0:.0f} s wall"
    )

    print(
        stats_line(
            "cut height error (range at EV_STOP - cut)", [r.get("cut_error") for r in rows], "cm", 100.0
        )
    )
    print(stats_line("EV_STOP -> EV_CONTACT", [r.get("contact_after_stop") for r in rows]))
    print(stats_line("EV_CONTACT -> EV_RVT", [r.get("impact_to_rvt") for r in rows]))


if __name__ == "__main__":
    main()
