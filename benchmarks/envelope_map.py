"""Time the full asymmetric map (61 slopes x 26 speeds x 16 torque pairs) and the lookup table.

    python3 benchmarks/envelope_map.py            # default 1 deg x 0.1 m/s grid

Prints seconds and landings per second. The first model call of a process compiles (~15 s);
it is done and timed separately, before the clock starts.
"""

from __future__ import annotations

import argparse
import datetime
import os
import time

from slopelander.envelope.axes import MapAxes
from slopelander.envelope.presets import choose_presets
from slopelander.envelope.table import build_table
from slopelander.model import Model, condition_grid, simulate_batch


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slope-step", type=float, default=1.0)
    ap.add_argument("--speed-step", type=float, default=0.1)
    args = ap.parse_args()
    model = Model.default()
    axes = MapAxes.build(args.slope_step, args.speed_step)
    t = time.perf_counter()
    simulate_batch(condition_grid(slope_deg=0.0, speed=1.0), model)
    print(f"compile/warm-up: {time.perf_counter() - t:.1f} s")
    print(
        f"{datetime.datetime.now():%Y-%m-%d %H:%M}, {os.cpu_count()} cores, "
        f"load average {os.getloadavg()[0]:.2f} before the run"
    )

    t = time.perf_counter()
    m = choose_presets(model, axes, "asymmetric", progress=False)
    dt = time.perf_counter() - t
    n = m.meta["landings_simulated"]
    print(
        f"asymmetric map {axes.shape[0]} x {axes.shape[1]} x 16 pairs = {n} landings: "
        f"{dt:.1f} s ({n / dt:.0f} landings/s)"
    )

    t = time.perf_counter()
    _, presets = build_table(model, axes, "rvt", progress=False)
    dt = time.perf_counter() - t
    s, v = axes.shape
    margins = 2 * s * (v - 1) + 2 * (s - 1) * v + 4 * (s - 1) * (v - 1)  # one per neighbour pair
    n = presets.meta["landings_simulated"] + margins
    print(
        f"lookup table (rvt presets + {margins} margin landings), {axes.size} cells: {dt:.1f} s "
        f"({n / dt:.0f} landings/s)"
    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
