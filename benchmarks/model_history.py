"""What each commit did to the compiled model's speed, measured side by side in one run.

Each commit's model (``past_model.py`` extracts it from git into a cache directory; the first
run compiles each one, about a minute apiece) simulates the same 200 drops as
``model_ratio.py`` (slopes 0-45 deg, 1-3 m/s, two torque levels, the model as shipped), on one
core, the commits taking turns in every round; then to rest. Prints landings per CPU-second
(median of rounds), each commit's speed against the one before it and against the first (the
median of the per-round ratios), and whether its outcomes are bit-identical to the first's.
"working tree" stands for the checkout's own, uncommitted code.

Usage: python benchmarks/model_history.py [COMMIT ...] [--rounds 7] [--no-working-tree]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from past_model import load_past_model

import slopelander.model as working_tree

# the seam table (e42852d) and the commits of its speed work
DEFAULT = ("67501ca", "87138a0", "99e0ac5", "1bab90c", "4a0a135", "86c7547", "fe70af9", "9da31d0")


def drops(mod) -> np.ndarray:
    g = mod.condition_grid(
        slope_deg=np.linspace(0.0, 45.0, 20),
        speed=np.array([1.0, 1.5, 2.0, 2.5, 3.0]),
        tau_up=np.array([1.1, 2.3]),
    )
    g["tau_down"] = g["tau_up"]
    g["reverse_percent"] = 0.0
    return g


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("commits", nargs="*", default=list(DEFAULT))
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--no-working-tree", action="store_true", help="leave out the uncommitted code")
    args = ap.parse_args()
    mods = {c: load_past_model(c) for c in args.commits}
    if not args.no_working_tree:
        mods["working tree"] = working_tree
    runs = {name: (mod, mod.Model.default(), drops(mod)) for name, mod in mods.items()}
    for mod, model, g in runs.values():  # compile or load each outside the timing
        mod.simulate_batch(g[:2], model, stop_at_rest=False)
    numba.set_num_threads(1)
    load = os.getloadavg()
    print(f"load average {load[0]:.1f} at start; {len(g)} drops, one core, {args.rounds} rounds")
    names = list(runs)
    for mode, rest in (("2 s", False), ("rest", True)):
        cpu = {n: [] for n in names}
        out = {}
        for _ in range(args.rounds):
            for n in names:
                mod, model, g = runs[n]
                c0 = time.process_time()
                out[n] = mod.simulate_batch(g, model, stop_at_rest=rest)
                cpu[n].append(time.process_time() - c0)
        first = names[0]
        print(f"\n{mode}: landings per CPU-second, against the one before, against {first}")
        for i, n in enumerate(names):
            rate = len(g) / float(np.median(cpu[n]))
            prev = np.median(np.array(cpu[names[i - 1]]) / np.array(cpu[n])) if i else 1.0
            base = np.median(np.array(cpu[first]) / np.array(cpu[n]))
            same = all(np.array_equal(out[n][f], out[first][f], equal_nan=True) for f in out[n].dtype.names)
            print(
                f"  {n:<13} {rate:7.1f}   {prev:5.2f}x   {base:5.2f}x   "
                f"{'bit-identical' if same else 'differs'} to {first}"
            )
    load = os.getloadavg()
    print(f"\nload average {load[0]:.1f} at the end")


if __name__ == "__main__":
    main()
