"""How much the compiled model's speed moves with where its workspace lies in memory, today's
integrator and a past commit's side by side, at the same places.

``model_history.py`` times each commit's ``run_batch``, which allocates the workspace record
wherever the allocator puts it; a commit that changes the record's size moves it. This script
runs the same 200 drops (``model_history.py``'s, to the 2 s horizon, one core) through each
integrator's ``_run_landing`` with a workspace it places itself, at the given offsets within a
4 KiB page, the integrators and offsets taking turns in every round. Prints landings per
CPU-second per integrator and offset (median of rounds), each integrator's spread over the
offsets, and today's speed against the past commit's at the same offset (median of the
per-round ratios), then the median of those ratios over the offsets.

Usage: python benchmarks/workspace_placement.py [COMMIT] [--offsets 0,256,...] [--rounds 3]
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from model_history import drops
from past_model import load_past_model

import slopelander.model as working_tree

PAGE = 4096


def setup(mod) -> tuple:
    """The kernel of a model package and the arguments of its ``_run_landing``."""
    k = importlib.import_module(mod.__name__ + ".kernel")
    model = mod.Model.default()
    g = drops(mod)
    conds = g.view(np.float64).reshape(len(g), k.N_COND).copy()
    return k, model.params.as_array(), model.flags(), conds, model.dt, model.criteria_array()


def workspace_at(k, offset: int) -> tuple[np.ndarray, np.ndarray]:
    """A workspace record ``offset`` bytes into a page, and the buffer that holds it."""
    n = k.WORKSPACE.itemsize
    buf = np.zeros(n + 2 * PAGE, np.uint8)
    start = (offset - buf.ctypes.data) % PAGE
    return buf[start : start + n].view(k.WORKSPACE), buf


def landings(s: tuple, ws: np.ndarray) -> float:
    """CPU seconds for every drop, each in a freshly zeroed workspace (as run_batch has it)."""
    k, p, fl, conds, h, crit = s
    rec = np.zeros((0, k.N_STATE))
    res = np.zeros(k.N_RESULT)
    c0 = time.process_time()
    for i in range(conds.shape[0]):
        ws[0] = 0
        k._run_landing(p, fl, conds[i], h, crit, False, 0, rec, None, res, ws)
    return time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("commit", nargs="?", default="cc09bc2")
    ap.add_argument("--offsets", default=",".join(str(o) for o in range(0, PAGE, 256)))
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    offsets = [int(o) % PAGE for o in args.offsets.split(",")]
    setups = {args.commit: setup(load_past_model(args.commit)), "working tree": setup(working_tree)}
    spaces = {(n, o): workspace_at(s[0], o) for n, s in setups.items() for o in offsets}
    for (n, _), (ws, _) in spaces.items():  # compile or load each outside the timing
        landings(setups[n], ws)
    numba.set_num_threads(1)
    print(f"load average {os.getloadavg()[0]:.1f} at start; {args.rounds} rounds")
    cpu = {key: [] for key in spaces}
    for _ in range(args.rounds):
        for key, (ws, _) in spaces.items():
            cpu[key].append(landings(setups[key[0]], ws))
    names = list(setups)
    n_drops = setups[names[0]][3].shape[0]
    print(f"\nlandings per CPU-second by page offset of the workspace; working tree against {names[0]}")
    ratios = []
    for o in offsets:
        past, now = np.array(cpu[(names[0], o)]), np.array(cpu[(names[1], o)])
        ratios.append(float(np.median(past / now)))
        print(
            f"  {o:5d}   {names[0]} {n_drops / np.median(past):7.1f}   working tree "
            f"{n_drops / np.median(now):7.1f}   {ratios[-1]:5.2f}x"
        )
    for n in names:
        rates = [n_drops / np.median(cpu[(n, o)]) for o in offsets]
        print(f"{n}: {min(rates):.1f} to {max(rates):.1f} landings per CPU-second over the offsets")
    same = float(np.median(ratios))
    print(f"working tree against {names[0]} at the same offset, median over the offsets: {same:.2f}x")
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
