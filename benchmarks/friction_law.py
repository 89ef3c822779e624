"""Foot friction law: what velocity weakening (Stribeck) changes, and why the FSA vehicle at rest
still cannot hold the static friction limit.

For the stick/slip law (a slipping foot feels mu_k) and for the velocity-weakening law at several
Stribeck speeds v_s, prints:

* the hold angle of the FSA vehicle at rest (set down with sticky feet, then given the law; the
  steepest whole degree on which it moves less than 5 cm in 2 s);
* the landing map with asymmetric torques and the paper's uphill angle, no thrust
  (``slopelander map angle``) at a coarse grid: maximum landed slope and areas;
* the 35 deg / 2.7 m/s drop without thrust at 1.7 N*m, at the default step and 10x finer.

Then the mechanism: the downhill foot's friction demand |F_t|/N at rest on 42 deg, for the
shipped bending stiffness of the legs and for legs ten times stiffer.

    python3 benchmarks/friction_law.py [--slope-step 2 --speed-step 0.5]
"""

from __future__ import annotations

import argparse
import math
import sys
import time

from slopelander.envelope.axes import MapAxes
from slopelander.envelope.maps import summary
from slopelander.envelope.presets import choose_presets
from slopelander.envelope.reports import _strategy
from slopelander.model import DEFAULT_DT, LandingConditions, Model, kernel, simulate
from slopelander.model.placement import settle_on_slope as settle
from slopelander.model.placement import slide_after as slide


def hold_angle(model: Model, start: int = 36, stop: int = 55) -> int:
    held = start - 1
    for a in range(start, stop):
        if abs(slide(settle(model, a), 2.0)) > 0.05:
            break
        held = a
    return held


def cost(rounds: int = 3) -> int:
    """Landings per CPU-second with and without the law, interleaved so that load changes hit
    both; CPU time (all threads) rather than wall time, as other work shares the machine."""
    import numpy as np

    from slopelander.model import simulate_batch
    from slopelander.model.conditions import condition_grid

    conds = condition_grid(
        slope_deg=np.arange(0.0, 61.0, 2.0), speed=np.arange(0.5, 3.01, 0.1), tau_up=[1.1, 2.3]
    )
    models = {"with": Model.default(), "without": Model.default().without("velocity_weakening_friction")}
    for m in models.values():
        simulate_batch(conds[:8], m)  # compile / load
    cpu: dict[str, list[float]] = {k: [] for k in models}
    for _ in range(rounds):
        for k, m in models.items():
            t = time.process_time()
            simulate_batch(conds, m)
            cpu[k].append(time.process_time() - t)
    rate = {k: len(conds) / min(v) for k, v in cpu.items()}
    print(f"{len(conds)} landings (stopping at rest), best of {rounds} interleaved runs:")
    for k, r in rate.items():
        print(f"  {k:8s} velocity weakening: {r:7.0f} landings per CPU-second")
    print(f"  ratio with / without: {rate['with'] / rate['without']:.2f}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slope-step", type=float, default=2.0)
    ap.add_argument("--speed-step", type=float, default=0.5)
    ap.add_argument("--speeds", type=float, nargs="*", default=[0.003, 0.01, 0.03, 0.1])
    ap.add_argument(
        "--cost", action="store_true", help="only the speed cost of the law: landings/s with and without"
    )
    a = ap.parse_args(argv)
    if a.cost:
        return cost()
    base = Model.default().without("velocity_weakening_friction")
    laws = {"stick/slip (mu_k while slipping)": base}
    for vs in a.speeds:
        laws[f"Stribeck v_s = {vs:g} m/s"] = base.with_effects("velocity_weakening_friction").with_params(
            provenance="assumed", stribeck_speed=vs
        )
    axes = MapAxes.build(a.slope_step, a.speed_step)
    drop = LandingConditions(slope_deg=35.0, speed=2.7, tau_up=1.7, tau_down=1.7)
    print(
        f"map angle (no thrust) at {a.slope_step:g} deg x {a.speed_step:g} m/s;",
        "35 deg / 2.7 m/s drop at 1.7 N*m",
    )
    print(
        f"{'law':34s} {'hold':>5s} {'max landed':>10s} {'max ideal':>9s} {'area ideal':>10s} "
        f"{'area landed':>11s}  drop 35/2.7 (default step | 10x finer)"
    )
    t0 = time.perf_counter()
    for name, m in laws.items():
        hold = hold_angle(m)
        mp = choose_presets(m, axes, _strategy("angle", False, False), progress=False)
        sm = summary(mp)
        r = [simulate(drop, m, dt=dt, full_horizon=False).result for dt in (DEFAULT_DT, DEFAULT_DT / 10)]
        d = " | ".join(f"{x.outcome.name.lower()} slide {x.slide:.3f} m" for x in r)
        print(
            f"{name:34s} {hold:4d}° {sm['max_slope_landed_deg']:9.0f}° {sm['max_slope_ideal_deg']:8.0f}° "
            f"{sm['area_ideal_deg_mps']:10.1f} {sm['area_landed_deg_mps']:11.1f}  {d}"
        )
        sys.stdout.flush()
    print(f"({time.perf_counter() - t0:.0f} s)")

    print("\nwhy: at rest on 42 deg after a sticky set-down (joints held at 5 N*m), per foot")
    m = Model.default()
    for label, kq in (
        ("shipped legs", m.params["flex_stiffness"]),
        ("legs 10x stiffer", 10 * m.params["flex_stiffness"]),
    ):
        s = settle(m.with_params(provenance="assumed", flex_stiffness=kq), 42.0)
        n = s.st[kernel.S_NF : kernel.S_NF + 2].copy()
        ft = s.st[kernel.S_FT : kernel.S_FT + 2].copy()
        d = slide(s, 2.0)
        print(
            f"  {label:17s} uphill foot N {n[0]:5.2f} N, F_t {ft[0]:+6.2f} N | "
            f"downhill foot N {n[1]:5.2f} N, "
            f"F_t {ft[1]:+6.2f} N, |F_t|/N {abs(ft[1]) / n[1]:.2f} (mu_s {m.params['friction_static']:.2f}, "
            f"tan 42 = {math.tan(math.radians(42)):.2f}) -> slides {d:.3f} m in 2 s"
        )
    print("  (F_t along the surface, + downhill: an uphill foot pushed + is held against the legs' splay)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
