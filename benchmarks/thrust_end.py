"""Does the vehicle hold once the reverse thrust ends? A step to zero against linear ramps.

The model alone (no processes): each landing flies the table's preset for its roof and impact
speed, 100 % reverse thrust from impact, ended once the body has read still for 0.2 s (at least
0.5 s after impact), as the companion's REVERSE state does; then the rotor command either steps
to zero or falls linearly to zero over R seconds. A landing *holds* when, 2 s after the thrust
is gone, the vehicle is still and has moved less than 2 cm down the slope. The friction
parameters are the model's defaults.

Prints, per roof, how many of its landings (impact speeds x horizontal speeds) hold for each
ending, and the total over the campaign's steep roofs (41-45 deg).

    python3 benchmarks/thrust_end.py [--ramps 0 0.25 0.5 0.75 1 1.5] [--slopes 41 42 43 44 45]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from slopelander.controller.table import DEFAULT_TABLE, LookupTable
from slopelander.model import LandingConditions, Model
from slopelander.model.thrust_end import ThrustEnd, land_and_end_thrust


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ramps", type=float, nargs="+", default=[0.0, 0.25, 0.5, 0.75, 1.0, 1.5])
    ap.add_argument("--slopes", type=float, nargs="+", default=[25, 30, 35, 38, 40, 41, 42, 43, 44, 45])
    ap.add_argument("--speeds", type=float, nargs="+", default=[1.5, 2.0, 2.5, 3.0])
    ap.add_argument("--vx", type=float, nargs="+", default=[-0.4, 0.0, 0.4])
    args = ap.parse_args(argv)
    table = LookupTable.load(DEFAULT_TABLE)
    model = Model.default()
    n = len(args.speeds) * len(args.vx)
    print(f"landings per roof: {n} (impact {args.speeds} m/s x horizontal {args.vx} m/s), table's presets")
    head = " ".join(f"{'step' if r == 0 else f'ramp {r:g} s':>10}" for r in args.ramps)
    print(f"{'roof':>5} {head}   worst slide (m) per ending")
    steep = np.zeros(len(args.ramps), dtype=int)
    n_steep = 0
    t0 = time.process_time()
    for slope in args.slopes:
        held = []
        worst = []
        for ramp in args.ramps:
            h, w = 0, 0.0
            for speed in args.speeds:
                pre = table.lookup(slope, speed)
                for vx in args.vx:
                    c = LandingConditions(
                        slope_deg=slope,
                        speed=speed,
                        horizontal_speed=vx,
                        tau_up=pre.tau_up,
                        tau_down=pre.tau_down,
                        angle_up_deg=pre.angle_up_deg,
                        angle_down_deg=pre.angle_down_deg,
                        reverse_percent=100.0,
                    )
                    r = land_and_end_thrust(c, ThrustEnd(ramp_s=ramp), model)
                    h += r.held()
                    w = max(w, abs(r.slide))
            held.append(h)
            worst.append(w)
        if 41 <= slope <= 45:
            steep += np.array(held)
            n_steep += n
        cells = " ".join(f"{f'{h}/{n}':>10}" for h in held)
        print(f"{slope:5.1f} {cells}   " + " ".join(f"{w:.2f}" for w in worst), flush=True)
    if n_steep:
        cells = " ".join(f"{f'{h}/{n_steep}':>10}" for h in steep)
        print(f"41-45 {cells}")
    print(f"cpu {time.process_time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
