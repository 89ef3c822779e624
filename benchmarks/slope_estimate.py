"""The slope estimate's error (bias, spread), its refusals and how often a wrong pilot's slope is
caught, on synthesized survey passes: offline, so that hundreds of passes cost seconds of one
core, not hundreds of flights.

Each pass is what the companion flies (controller/survey.py: spot, 1 m south, 2 m north, back;
0.4 m/s, up to 1 m/s^2 at the turns) over the simulated vehicle's world (sitl/vehicle/world.py:
the roof face, its beam of 2 deg read as a mean, the scenario's 5 mm range noise) at 20 Hz of
range, ATTITUDE at 10 Hz and LOCAL_POSITION_NED at 20 Hz (the rates ``slopelander land`` asks
for). The errors a real vehicle adds: pitch from the pass's acceleration, a per-pass attitude
bias (1 sigma ``--att-bias`` deg) and noise (0.2 deg), a height drift (random walk, 1 cm/sqrt(s))
and the range reading's 50 ms age (ArduCopter's 20 Hz task). The estimator is the companion's
own (``slopelander.controller.slope_estimate``) with the shipped settings.

    python3 benchmarks/slope_estimate.py [--runs 40] [--att-bias 0.5] [--beam-deg 2] [--return mean]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import itertools

from sitl.vehicle.world import Beam, World, beam_at
from slopelander.controller.config import load_config
from slopelander.controller.slope_estimate import (
    EstimateSettings,
    SurfaceTrack,
    check_bound,
    estimate,
    pilot_refusal,
)

SPOT_X = 5.5
G = 9.80665
RANGE_MAX_M = 14.0  # the simulated vehicle's RNGFND1_MAX


def pass_profile(length: float, speed: float, accel: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """x(t) and its acceleration of the pass: a target moving at ``speed`` through the legs, the
    vehicle following with at most ``accel``; 1.5 s of settling at the end."""
    legs = [SPOT_X, SPOT_X - length / 2, SPOT_X + length / 2, SPOT_X]
    xs, acc = [SPOT_X], [0.0]
    x, v = SPOT_X, 0.0
    for a, b in itertools.pairwise(legs):
        d = math.copysign(1.0, b - a)
        while (b - x) * d > 1e-3:
            # brake to stop at b, else speed up to `speed`
            stop = v * v / (2 * accel)
            want = 0.0 if abs(b - x) <= stop + 1e-9 else d * speed
            dv = max(-accel * dt, min(accel * dt, want - v))
            v += dv
            x += v * dt
            xs.append(x)
            acc.append(dv / dt)
            if abs(v) < 1e-6 and want == 0.0:
                break
    for _ in range(int(1.5 / dt)):
        xs.append(x)
        acc.append(0.0)
    return np.array(xs), np.array(acc)


def one_pass(
    slope_deg: float, height: float, rng: np.random.Generator, args, st: EstimateSettings
) -> tuple[object, float]:
    world = World(slope_deg, 3.0, 0.5, beam=Beam(args.beam_deg, args.ret, 0.1))
    dt = 0.0025  # the vehicle's 400 Hz control tick
    xs, acc = pass_profile(2.0, 0.4, 1.0, dt)
    t = np.arange(xs.size) * dt
    surf = world.roof_z - (SPOT_X - world.roof_x) * math.tan(math.radians(slope_deg))
    z_up = surf + height
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=40, help="passes per (slope, height) (default 40)")
    ap.add_argument("--att-bias", type=float, default=0.5, help="attitude bias, 1 sigma deg (default 0.5)")
    ap.add_argument("--beam-deg", type=float, default=2.0, help="full beam width, deg (default 2)")
    ap.add_argument("--return", dest="ret", choices=("mean", "nearest"), default="mean")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    cfg = load_config()
    st = EstimateSettings.from_config(cfg)
    rng = np.random.default_rng(args.seed)
    slopes = [0, 10, 20, 30, 35, 40, 50, 60]
    heights = [1.0, 2.0, 3.0]
    t0 = time.process_time()
    print(f"runs {args.runs}, attitude bias {args.att_bias} deg, beam {args.beam_deg} deg ({args.ret})")
    print("slope  height  bias   spread  mean-sigma  |err|<=2sig  refused  caught+-10  caught+-20  false-ref")
    pass_s = None
    for h in heights:
        for s in slopes:
            errs, sig, cover, refused, caught10, n10, caught20, n20, false = [], [], 0, 0, 0, 0, 0, 0, 0
            for _ in range(args.runs):
                est, pass_s = one_pass(s, h, rng, args, st)
                if not est.ok:
                    refused += 1
                    continue
                e = est.slope_deg - s
                errs.append(e)
                sig.append(est.sigma_deg)
                cover += abs(e) <= 2 * est.sigma_deg
                bound = check_bound(
                    5.0, est.sigma_deg, cfg["slope.check_sigmas"], cfg["slope.check_bound_deg"]
                )
                false += pilot_refusal(float(s), est, bound) is not None
                for off in (-10, 10):
                    if 0 <= s + off <= 60:
                        n10 += 1
                        caught10 += pilot_refusal(float(s + off), est, bound) is not None
                for off in (-20, 20):
                    if 0 <= s + off <= 60:
                        n20 += 1
                        caught20 += pilot_refusal(float(s + off), est, bound) is not None
            ok = len(errs)
            if ok:
                print(
                    f"{s:5.0f}  {h:5.1f}  {np.mean(errs):+6.2f}  {np.std(errs):6.2f}  {np.mean(sig):9.2f}  "
                    f"{cover / ok:10.0%}  {refused / args.runs:7.0%}  "
                    f"{caught10 / max(1, n10):10.0%}  {caught20 / max(1, n20):10.0%}  {false / ok:12.0%}"
                )
            else:
                print(f"{s:5.0f}  {h:5.1f}  all {args.runs} refused")
    print(f"pass duration (target motion 10 s + settling): {pass_s:.1f} s vehicle time")
    print(f"CPU {time.process_time() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
