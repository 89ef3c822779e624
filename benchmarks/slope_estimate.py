"""The slope estimate's error (bias, spread), its refusals and how often a wrong pilot's slope is
caught, on synthesized survey passes: offline, so that hundreds of passes cost seconds of one
core, not hundreds of flights.

Each pass is what the companion flies (controller/survey.py: spot, 1 m south, 2 m north, back;
0.4 m/s, up to 1 m/s^2 at the turns) over the simulated vehicle's world
(src/slopelander_sitl/vehicle/world.py:
the roof face, its beam of 2 deg read as a mean, the scenario's 5 mm range noise) at 20 Hz of
range, ATTITUDE at 10 Hz and LOCAL_POSITION_NED at 20 Hz (the rates ``slopelander land`` asks
for). The errors a real vehicle adds: pitch from the pass's acceleration, a per-pass attitude
bias (1 sigma ``--att-bias`` deg) and noise (0.2 deg), a height drift (random walk, 1 cm/sqrt(s))
and the range reading's 50 ms age (ArduCopter's 20 Hz task). The estimator is the companion's
own (``slopelander.controller.slope_estimate``) with the shipped settings.

    python3 benchmarks/slope_estimate.py [--runs 40] [--att-bias 0.5] [--beam-deg 2] [--return mean]

``--flown`` flies the passes instead, on the simulated vehicle or on real ArduCopter SITL
(``--autopilot ardupilot``, its binary from ``--arducopter`` or ``SLOPELANDER_ARDUCOPTER``): one
vehicle per slope over the roof's spot (the rig's), each pass the companion's own
``survey.measure_slope`` with a track of its own; ``--save FILE`` keeps every estimate with its
points. A flown pass costs its 11-12 s of vehicle time plus the repositioning, so keep the subset
small (``--slopes``, ``--heights``, ``--runs``); ArduCopter at ``--speedup 1`` on a loaded machine.

    python3 benchmarks/slope_estimate.py --flown --autopilot ardupilot --speedup 1 --runs 2 \
        --slopes 0,10,20,35 --heights 1,2,3 --save passes.jsonl
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


from slopelander.controller.config import load_config
from slopelander.controller.slope_estimate import (
    EstimateSettings,
    SurfaceTrack,
    check_bound,
    estimate,
    pilot_refusal,
)
from slopelander.controller.survey import low_range
from slopelander_sitl.vehicle.world import Beam, World, beam_at

SPOT_X = 5.5
G = 9.80665
RANGE_MAX_M = 3.0  # RNGFND1_MAX of every parameter file: the TeraRanger Evo 3m


def pass_profile(
    length: float, speed: float, accel: float, dt: float, range_at=None, min_range: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """x(t) and its acceleration of the pass: a target moving at ``speed`` through the legs, the
    vehicle following with at most ``accel``; 1.5 s of settling at the end. With ``range_at``
    (x -> the range a level body reads there) the companion's guard turns an outward leg back
    where the range will fall below ``min_range`` (controller/survey.py: ``low_range`` on the
    20 Hz readings, 50 ms old)."""
    goals = [SPOT_X - length / 2, SPOT_X + length / 2, SPOT_X]
    xs, acc = [SPOT_X], [0.0]
    x, v = SPOT_X, 0.0
    seen = SurfaceTrack(0.1)
    t = 0.0
    k = 0
    while k < len(goals):
        b = goals[k]
        d = math.copysign(1.0, b - x)
        # brake to stop at b, else speed up to `speed`
        stop = v * v / (2 * accel)
        want = 0.0 if abs(b - x) <= stop + 1e-9 else d * speed
        dv = max(-accel * dt, min(accel * dt, want - v))
        v += dv
        x += v * dt
        t += dt
        xs.append(x)
        acc.append(dv / dt)
        if range_at is not None and round(t * 1000) % 50 == 25:
            r = range_at(xs[max(0, len(xs) - 1 - round(0.05 / dt))])
            if math.isfinite(r) and r < RANGE_MAX_M:
                seen.add(t, range_m=r)
                guarded = k == 0 or (k == 1 and x >= SPOT_X)
                if guarded and low_range(seen, t, min_range) is not None:
                    k += 1  # turned back where the vehicle is
                    continue
        if ((b - x) * d <= 1e-3) or (abs(v) < 1e-6 and want == 0.0):
            k += 1
    for _ in range(int(1.5 / dt)):
        xs.append(x)
        acc.append(0.0)
    return np.array(xs), np.array(acc)


def one_pass(
    slope_deg: float, height: float, rng: np.random.Generator, args, st: EstimateSettings
) -> tuple[object, float]:
    world = World(slope_deg, 3.0, 0.5, beam=Beam(args.beam_deg, args.ret, 0.1))
    dt = 0.0025  # the vehicle's 400 Hz control tick
    surf = world.roof_z - (SPOT_X - world.roof_x) * math.tan(math.radians(slope_deg))
    z_up = surf + height
    xs, acc = pass_profile(2.0, 0.4, 1.0, dt, lambda x: beam_at(world, x, z_up, 0.0), args.min_range)
    t = np.arange(xs.size) * dt
    bias = math.radians(rng.normal(0, args.att_bias))
    drift = np.cumsum(rng.normal(0, 0.01 * math.sqrt(dt), xs.size))
    tr = SurfaceTrack(0.1)
    for i in range(xs.size):
        pitch = -math.atan2(acc[i], G)
        ms = round(t[i] * 1000)
        if ms % 100 == 0:  # ATTITUDE 10 Hz, with its bias and noise
            tr.add(t[i], attitude=(0.0, pitch + bias + math.radians(rng.normal(0, 0.2)), 0.0))
        if ms % 50 == 0:  # LOCAL_POSITION_NED 20 Hz, the height drifting
            tr.add(t[i], position=(xs[i], 0.0, -(z_up + drift[i])))
        if ms % 50 == 25:  # the range, 20 Hz, stamped when sent: 50 ms after it was taken
            j = max(0, i - 20)
            r = beam_at(world, xs[j], z_up, -math.atan2(acc[j], G))
            if math.isfinite(r) and 0.05 < r < RANGE_MAX_M:
                tr.add(t[i], range_m=r + rng.normal(0, 0.005))
    return estimate(tr.points(), SPOT_X, st), float(t[-1])


HEADER = (
    "slope  height  bias   spread  mean-sigma  |err|<=1sig  |err|<=2sig  refused  caught+-10  caught+-20  "
    "false-ref  survey-s"
)


def row(s: float, h: float, results: list[tuple[object, float]], cfg) -> str:
    """One line of the table from the (estimate, survey seconds) of the passes at slope ``s``,
    height ``h``."""
    errs, sig, cover1, cover, refused, false = [], [], 0, 0, 0, 0
    caught = {10: [0, 0], 20: [0, 0]}
    for est, _took in results:
        if not est.ok:
            refused += 1
            continue
        e = est.slope_deg - s
        errs.append(e)
        sig.append(est.sigma_deg)
        cover1 += abs(e) <= est.sigma_deg
        cover += abs(e) <= 2 * est.sigma_deg
        bound = check_bound(5.0, est.sigma_deg, cfg["slope.check_sigmas"], cfg["slope.check_bound_deg"])
        false += pilot_refusal(float(s), est, bound) is not None
        for off, tally in caught.items():
            for pilot in (s - off, s + off):
                if 0 <= pilot <= 60:
                    tally[1] += 1
                    tally[0] += pilot_refusal(float(pilot), est, bound) is not None
    ok, n = len(errs), len(results)
    if not n:
        return f"{s:5.0f}  {h:5.1f}  no pass flown"
    took = np.mean([t for _e, t in results])
    if not ok:
        return f"{s:5.0f}  {h:5.1f}  all {n} refused{'':70}{took:8.1f}"
    return (
        f"{s:5.0f}  {h:5.1f}  {np.mean(errs):+6.2f}  {np.std(errs):6.2f}  {np.mean(sig):9.2f}  "
        f"{cover1 / ok:10.0%}  {cover / ok:10.0%}  {refused / n:7.0%}  "
        f"{caught[10][0] / max(1, caught[10][1]):10.0%}  {caught[20][0] / max(1, caught[20][1]):10.0%}  "
        f"{false / ok:9.0%}  {took:8.1f}"
    )


def synthesized(args, cfg, st, slopes, heights) -> None:
    rng = np.random.default_rng(args.seed)
    print(f"synthesized, runs {args.runs}, attitude bias {args.att_bias} deg, ", end="")
    print(f"beam {args.beam_deg} deg ({args.ret})")
    print(HEADER)
    for h in heights:
        for s in slopes:
            print(row(s, h, [one_pass(s, h, rng, args, st) for _ in range(args.runs)], cfg), flush=True)


class Current:
    """Feeds the track of the pass being flown (a fresh one per pass: no point of an earlier pass)."""

    track: SurfaceTrack | None = None

    def feed(self, msg) -> None:
        if self.track is not None:
            self.track.feed(msg)


def flown(args, cfg, slopes, heights) -> None:
    """Survey passes flown by the companion's own ``measure_slope`` on a vehicle (one per slope,
    the heights and runs in turn over the roof's spot, each pass with a track of its own)."""
    import json

    from slopelander.controller.survey import measure_slope
    from slopelander.legs.errors import LegBoardError
    from slopelander_sitl.rig import Rig, RigError

    print(
        f"flown on {args.autopilot}, runs {args.runs}"
        + (f", speedup {args.speedup:g}" if args.autopilot == "ardupilot" else "")
    )
    print(HEADER)
    save = open(args.save, "a") if args.save else None  # noqa: SIM115
    for s in slopes:
        by_height: dict[float, list] = {h: [] for h in heights}
        todo = [h for h in heights for _ in range(args.runs)]
        for attempt in (1, 2):  # a vehicle lost to a loaded machine (a silent board): a fresh one, once
            try:
                with Rig(
                    slope_deg=s,
                    seed=int(s) + 100 * attempt + 1000 * args.seed,
                    autopilot=args.autopilot,
                    arducopter=args.arducopter,
                    arducopter_speedup=args.speedup,
                ) as rig:
                    rig.take_off(3.0)
                    current = Current()
                    rig.link.add_listener(current.feed)
                    while todo:
                        h = todo[0]
                        rig.go_over_roof(h)
                        current.track = SurfaceTrack(cfg["slope.pair_window_s"])
                        est, took = measure_slope(
                            rig.link, cfg, current.track, tick=rig.poll, note=lambda _: None
                        )
                        if est.refusal and est.refusal.startswith("survey pass not finished"):
                            raise RigError(est.refusal)
                        by_height[h].append((est, took))
                        todo.pop(0)
                        if save:
                            rec = {"autopilot": args.autopilot, "slope": s, "height": h, "took_s": took}
                            save.write(json.dumps({**rec, **est.record()}) + "\n")
                            save.flush()
                break
            except (LegBoardError, RigError) as exc:
                print(f"# slope {s:g}: vehicle lost ({exc}); {len(todo)} passes left", flush=True)
        for h in heights:
            print(row(s, h, by_height[h], cfg), flush=True)
    if save:
        save.close()


def height_walk(rec: dict) -> float | None:
    """The height's random-walk intensity (m per sqrt(s)) seen in one flown pass: the points'
    heights about the true slope (a free offset), their semivariogram at 0.05 s and 4 s of lag,
    gamma(L) = noise^2 + q^2 L / 2. None without enough points."""
    pts = np.array(rec.get("points") or [], float).reshape(-1, 4)
    if len(pts) < 30:
        return None
    t, x, h = pts[:, 0], pts[:, 1], pts[:, 2]
    r = h + (x - rec["spot_x_m"]) * math.tan(math.radians(rec["slope"]))
    gamma = []
    for lag in (0.05, 4.0):
        j = np.searchsorted(t, t + lag)
        ok = (j < t.size) & (np.abs(t[np.minimum(j, t.size - 1)] - t - lag) < 0.03)
        d = r[j[ok]] - r[ok]
        gamma.append(0.5 * float(np.mean(d * d)) if d.size else math.nan)
    return math.sqrt(max(0.0, 2 * (gamma[1] - gamma[0]) / (4.0 - 0.05)))


def summarize(files: list[str], cfg) -> None:
    """The table from passes saved by ``--flown --save`` (any number of files, pooled), and the
    height's wander each autopilot showed."""
    import json

    from slopelander.controller.slope_estimate import SlopeEstimate

    recs = [json.loads(line) for f in files for line in open(f) if line.strip()]  # noqa: SIM115
    for ap in sorted({r["autopilot"] for r in recs}):
        mine = [r for r in recs if r["autopilot"] == ap]
        print(f"flown on {ap}: {len(mine)} passes from {', '.join(files)}")
        print(HEADER)
        for s in sorted({r["slope"] for r in mine}):
            for h in sorted({r["height"] for r in mine if r["slope"] == s}):
                cell = [
                    (SlopeEstimate(r["slope_deg"], r["sigma_deg"], r["refusal"], r["spot_x_m"]), r["took_s"])
                    for r in mine
                    if r["slope"] == s and r["height"] == h
                ]
                print(row(s, h, cell, cfg))
        for s in sorted({r["slope"] for r in mine}):
            q = [v for r in mine if r["slope"] == s and (v := height_walk(r)) is not None]
            if q:
                print(
                    f"height wander over {s:g} deg (cm per sqrt(s)): median {np.median(q) * 100:.2f}, "
                    f"max {max(q) * 100:.2f} ({len(q)} passes)"
                )


def main(argv: list[str] | None = None) -> int:
    from slopelander_sitl.rig import add_autopilot_args

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=40, help="passes per (slope, height) (default 40)")
    ap.add_argument("--att-bias", type=float, default=0.5, help="attitude bias, 1 sigma deg (default 0.5)")
    ap.add_argument("--beam-deg", type=float, default=2.0, help="full beam width, deg (default 2)")
    ap.add_argument("--return", dest="ret", choices=("mean", "nearest"), default="mean")
    ap.add_argument(
        "--seed", type=int, default=1, help="of the synthesized errors, or of the flown scenarios"
    )
    ap.add_argument("--slopes", default="0,10,20,30,35,40,50,60", help="true slopes, deg (comma-separated)")
    ap.add_argument("--heights", default="1,2,3", help="heights over the spot, m (comma-separated)")
    ap.add_argument(
        "--flown", action="store_true", help="fly the passes on --autopilot instead of synthesizing them"
    )
    ap.add_argument(
        "--save", metavar="FILE", help="(--flown) append each pass's estimate and points as a JSON line"
    )
    ap.add_argument("--summarize", nargs="+", metavar="FILE", help="tabulate passes saved by --flown --save")
    add_autopilot_args(ap)
    args = ap.parse_args(argv)
    cfg = load_config()
    if args.summarize:
        summarize(args.summarize, cfg)
        return 0
    st = EstimateSettings.from_config(cfg)
    args.min_range = cfg["slope.survey_min_range_m"]
    slopes = [float(v) for v in args.slopes.split(",")]
    heights = [float(v) for v in args.heights.split(",")]
    if args.autopilot == "ardupilot" and not args.flown:
        ap.error("--autopilot ardupilot flies the passes: add --flown")
    if args.autopilot == "ardupilot":
        from slopelander_sitl.ardupilot.launch import ArduCopterMissingError, arducopter_binary

        try:
            arducopter_binary(args.arducopter)
        except ArduCopterMissingError as exc:
            ap.error(str(exc))
    t0, w0 = time.process_time(), time.monotonic()
    if args.flown:
        flown(args, cfg, slopes, heights)
    else:
        synthesized(args, cfg, st, slopes, heights)
    print("survey-s: vehicle seconds the pass added (target motion 10 s + settling)")
    print(f"CPU {time.process_time() - t0:.1f} s (this process), wall {time.monotonic() - w0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
