"""Step size: how far landings at the default step are from the same landings at a finer step.

Runs each landing at the default step (1/2400 s, 16 sub-steps per impact), at half of it and at a
tenth of it, and prints outcome, slide, peak compressions and the most negative pitch, then the
largest differences from the finest step. The cases add bouncing, sliding landings on 35-45 deg
without thrust (the feet slide and catch, the vehicle rocks) to the gentle ones the default step
was first chosen on.

    python3 benchmarks/step_convergence.py
"""

from __future__ import annotations

import sys
import time

from slopelander.model import DEFAULT_DT, LandingConditions, Model, simulate

GENTLE = [
    LandingConditions(slope_deg=0.0, speed=3.0, tau_up=2.3, tau_down=2.3),
    LandingConditions(slope_deg=20.0, speed=2.5, tau_up=1.1, tau_down=1.7),
    LandingConditions(
        slope_deg=35.0, speed=2.0, tau_up=1.1, tau_down=2.3, angle_up_deg=27.0, reverse_percent=100.0
    ),
]
SLIDING = [
    LandingConditions(slope_deg=35.0, speed=2.7, tau_up=t, tau_down=t) for t in (0.56, 1.1, 1.7, 2.3)
] + [
    LandingConditions(slope_deg=35.0, speed=2.7, tau_up=1.1, tau_down=1.7, angle_up_deg=27.0),
    LandingConditions(slope_deg=38.0, speed=1.5, tau_up=1.1, tau_down=1.7, angle_up_deg=25.0),
    LandingConditions(slope_deg=40.0, speed=1.0, tau_up=1.1, tau_down=1.7, angle_up_deg=24.0),
    LandingConditions(slope_deg=45.0, speed=2.0, tau_up=1.1, tau_down=1.7, angle_up_deg=22.0),
]
FIELDS = ("slide", "compression_up", "compression_down", "min_pitch_deg")


def main() -> int:
    model = Model.default()
    steps = (DEFAULT_DT, DEFAULT_DT / 2, DEFAULT_DT / 10)
    print("step: " + ", ".join(f"{dt * 1e3:.4f} ms" for dt in steps))
    print(
        f"{'landing':38s} {'step':>8s} {'outcome':12s} {'slide m':>8s} {'comp up':>8s} "
        f"{'comp dn':>8s} {'min pitch':>9s}"
    )
    worst: dict[str, dict[str, float]] = {"gentle": {}, "sliding": {}}
    flips = {"gentle": 0, "sliding": 0}
    t0 = time.perf_counter()
    for group, cases in (("gentle", GENTLE), ("sliding", SLIDING)):
        for c in cases:
            label = (
                f"{c.slope_deg:g} deg {c.speed:g} m/s {c.tau_up:g}/{c.tau_down:g} N*m "
                f"q_up {c.angle_up_deg:g}{' RVT' if c.reverse_percent else ''}"
            )
            rs = [simulate(c, model, dt=dt, full_horizon=False).result for dt in steps]
            for dt, r in zip(steps, rs, strict=True):
                print(
                    f"{label:38s} {dt * 1e3:8.4f} {r.outcome.name.lower():12s} {r.slide:8.3f} "
                    f"{r.compression_up:8.3f} {r.compression_down:8.3f} {r.min_pitch_deg:9.1f}"
                )
                label = ""
            fine = rs[-1]
            if rs[0].outcome != fine.outcome:
                flips[group] += 1
            for f in FIELDS:
                err = abs(getattr(rs[0], f) - getattr(fine, f))
                worst[group][f] = max(worst[group].get(f, 0.0), err)
    print(f"({time.perf_counter() - t0:.0f} s)\n")
    print("largest |default - 10x finer|:")
    for group, w in worst.items():
        n = len(GENTLE if group == "gentle" else SLIDING)
        items = ", ".join(f"{f} {v:.3f}" for f, v in w.items())
        print(f"  {group:8s} ({n} landings): {items}; outcome differs in {flips[group]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
