"""Landings per second of the planar model on this machine, against scipy's solve_ivp.

Prints, for the same set of full-model landings (2 s horizon, every effect on, slopes 0-60 deg,
impact speeds 0.5-3 m/s, the paper's torque levels, with and without reverse thrust):

* the compiled batch path on all cores, stopping each landing once the vehicle is at rest
  (what the maps use) and running every landing to the full 2 s;
* the same equations integrated event to event by ``solve_ivp`` (Radau) for a sample of them,
  with how well the two agree;
* the stepper's speed at ArduPilot's 1200 Hz physics rate, as a multiple of real time.

The rates printed are this machine's at this hour (they move 3-4x with its load); to see a
regression, compare with a reference in the same run: ``benchmarks/model_ratio.py`` (against a
past commit's integrator and the MuJoCo peer) or ``benchmarks/model_history.py`` (commit by commit).

Usage: python benchmarks/model_speed.py [--landings 4000] [--reference 24] [--effects-file FILE]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from dataclasses import asdict

import numpy as np

from slopelander.model import (
    LandingConditions,
    Model,
    Outcome,
    condition_grid,
    load_effects,
    simulate,
    simulate_batch,
)
from slopelander.model.reference import ReferenceLanding
from slopelander.model.stepper import Stepper


def landing_set(n: int, seed: int = 7) -> np.ndarray:
    """n conditions drawn across the envelope the maps cover."""
    rng = np.random.default_rng(seed)
    levels = np.array([0.56, 1.1, 1.7, 2.3])
    g = condition_grid(slope_deg=np.zeros(n))
    g["slope_deg"] = rng.uniform(0, 60, n)
    g["speed"] = rng.uniform(0.5, 3.0, n)
    g["tau_up"] = rng.choice(levels, n)
    g["tau_down"] = rng.choice(levels, n)
    g["angle_up_deg"] = np.clip(37.5 - 13.5 * g["slope_deg"] / 40.0, 24.0, 37.5)
    g["reverse_percent"] = rng.choice([0.0, 100.0], n)
    return g


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--landings", type=int, default=4000)
    ap.add_argument("--reference", type=int, default=24, help="landings through solve_ivp")
    ap.add_argument("--effects-file", help="add the user effects of this file (docs/effects.md)")
    args = ap.parse_args()
    model = Model.default()
    if args.effects_file:
        for effect in load_effects(args.effects_file):
            model = model.with_user_effect(effect)
        print(f"user effects: {', '.join(e.name for e in model.user_effects)}")
    conds = landing_set(args.landings)
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
        f"model dt {model.dt * 1e3:g} ms, horizon {model.criteria.horizon:g} s"
    )
    simulate_batch(conds[:8], model)  # compile (or load the cache) outside the timing
    simulate_batch(conds[:8], model, stop_at_rest=False)

    t0 = time.perf_counter()
    res = simulate_batch(conds, model)
    t_rest = time.perf_counter() - t0
    t0 = time.perf_counter()
    res_full = simulate_batch(conds, model, stop_at_rest=False)
    t_full = time.perf_counter() - t0
    same = np.mean(res["outcome"] == res_full["outcome"])
    print(
        f"compiled, stop at rest : {len(conds) / t_rest:8.0f} landings/s  "
        f"({len(conds)} in {t_rest:.2f} s, mean simulated {res['t_end'].mean():.2f} s each)"
    )
    print(
        f"compiled, full 2 s     : {len(conds) / t_full:8.0f} landings/s  "
        f"({len(conds)} in {t_full:.2f} s); same outcome as stopping at rest: {100 * same:.1f} %"
    )

    if args.reference > 0 and not model.user_effects:  # the reference knows built-ins only
        # the reference, on a sample, over the same time span as the kernel's run
        idx = np.linspace(0, len(conds) - 1, args.reference).astype(int)
        agree = 0
        diffs = []
        t_ref = 0.0
        for i in idx:
            c = LandingConditions(**{n: float(conds[i][n]) for n in conds.dtype.names})
            kr = simulate(c, model, full_horizon=False).result
            t0 = time.perf_counter()
            ref = ReferenceLanding(model, c)
            # a flip ends the kernel's run at -80 deg; let the reference reach its own flip
            ts, ys, _ = ref.run(kr.t_end + (0.1 if kr.outcome == Outcome.FLIP else 0.0))
            rr = ref.result(ts, ys, settled=kr.outcome.value < Outcome.SLID.value)
            t_ref += time.perf_counter() - t0
            agree += rr.outcome == kr.outcome
            diffs.append(
                [
                    abs(kr.compression_up - rr.compression_up),
                    abs(kr.compression_down - rr.compression_down),
                    abs(kr.slide - rr.slide),
                    abs(kr.min_pitch_deg - rr.min_pitch_deg),
                ]
            )
        d = np.array(diffs)
        # the kernel's time for exactly these landings, single-threaded would be unfair to neither:
        # both are quoted per landing of the sample, the kernel on all cores as it runs in sweeps
        t0 = time.perf_counter()
        simulate_batch(conds[idx], model)
        t_k = time.perf_counter() - t0
        print(f"solve_ivp (Radau+events): {len(idx) / t_ref:6.2f} landings/s  ({len(idx)} in {t_ref:.1f} s)")
        print(
            f"speed-up of the compiled batch over solve_ivp on the same landings: "
            f"{(t_ref / len(idx)) / (t_k / len(idx)):.0f}x  (over the full set's rate: "
            f"{(len(conds) / t_rest) / (len(idx) / t_ref):.0f}x)"
        )
        print(
            f"agreement on {len(idx)} landings: same outcome class {agree}/{len(idx)}; "
            f"median |difference| compression {np.median(d[:, :2]):.3f}, "
            f"slide {np.median(d[:, 2]) * 1e3:.1f} mm, "
            f"pitch {np.median(d[:, 3]):.2f} deg; "
            f"90th percentile compression {np.percentile(d[:, :2], 90):.3f}"
        )

    s = Stepper(model, slope_deg=20.0)
    u = s.hover_command()
    s.place(height=1.0, rotor_speed=u)
    s.step(1 / 1200, u, u)  # compile (or load the cache) outside the timing
    s.place(height=1.0, rotor_speed=u)
    n = 1200 * 5
    t0 = time.perf_counter()
    for i in range(n):
        s.step(1 / 1200, u * 0.9 if i > 600 else u, u * 0.9 if i > 600 else u)
    wall = time.perf_counter() - t0
    print(
        f"stepper at 1200 Hz: {n / 1200 / wall:.0f}x real time (5 s of descent and touchdown in "
        f"{wall:.2f} s; {wall / n * 1e6:.0f} us per tick)"
    )
    print(f"criteria: {asdict(model.criteria)}")


if __name__ == "__main__":
    main()
