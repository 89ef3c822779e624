"""What the reading of a planar leg changes in the maps: a pair of real legs or one.

``joints_per_planar_leg`` = 2 (shipped) makes a planar joint apply twice the per-joint torque,
with twice one leg's bending stiffness and damping; 1 makes it one real leg. This runs the
symmetric map (Fig. 8, both legs at 1.7 N*m, no thrust) and the FSA + RVT map (Fig. 10, best of
the 16 torque pairs) under both readings and prints the cells per outcome class and the areas,
beside the energy shares of ``benchmarks/energy_split.py``.

    python benchmarks/planar_leg_maps.py [--slope-step 1] [--speed-step 0.1]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src")]

from slopelander.envelope.axes import MapAxes  # noqa: E402
from slopelander.envelope.maps import envelope_area, max_slope  # noqa: E402
from slopelander.envelope.presets import choose_presets  # noqa: E402
from slopelander.model import Model, Outcome  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slope-step", type=float, default=1.0)
    ap.add_argument("--speed-step", type=float, default=0.1)
    a = ap.parse_args()
    axes = MapAxes.build(a.slope_step, a.speed_step)
    base = Model.default()
    readings = {
        "pair (2, shipped)": base,
        "one leg (1)": base.with_params("assumed", joints_per_planar_leg=1.0),
    }
    names = [str(o) for o in Outcome]
    print(f"grid {axes.shape[0]} x {axes.shape[1]}; cells per outcome class")
    print("| map | reading | " + " | ".join(names) + " | ideal area | landed area | max ideal slope |")
    print("|---" * (len(names) + 5) + "|")
    for strategy in ("symmetric", "rvt"):
        for label, model in readings.items():
            t0 = time.perf_counter()
            m = choose_presets(model, axes, strategy, progress=False)
            counts = [int((m.outcome == o).sum()) for o in Outcome]
            print(
                f"| {strategy} | {label} | "
                + " | ".join(map(str, counts))
                + f" | {envelope_area(m):.1f} | {envelope_area(m, 'landed'):.1f} | {max_slope(m):g} |"
                + f" <!-- {time.perf_counter() - t0:.0f} s -->"
            )


if __name__ == "__main__":
    main()
