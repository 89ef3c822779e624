"""Dask on this machine: the speed-up from 1 to 2 workers, a task's overhead, and the break-even.

    python3 benchmarks/dask_scaling.py                 # about 2-4 minutes on 2 busy cores
    python3 benchmarks/dask_scaling.py --sizes 64 256   # fewer grid sizes

Starts a real ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1 (one thread each,
as docs/cluster.md advises) and measures, in the same run and on the same landings (a map's
mix: slopes 0-60 deg, speeds 0.5-3 m/s, the 16 torque-level pairs):

- the single-process baseline: ``simulate_batch`` on one thread and on every core;
- ``run_sweep`` on the cluster with 1 worker, then with 2, for each grid size (its tasks cut
  as ``--dask`` cuts them); each configuration in turn, repeated, the best time kept;
- a task's overhead: many tasks of no landing through the same path (submit, the version
  check, the result back), and the same figure from the sweeps (cluster time less the
  single-thread time, over the tasks);
- fit evaluations (the residuals of parameter points over drops), one process vs the cluster.

From these it prints the smallest task worth sending (overhead under 5 %) and the grid size
from which 2 workers beat 1.
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from slopelander.envelope.cluster import fingerprint, warm_up
from slopelander.envelope.sweep import run_sweep, simulate_chunk, task_size
from slopelander.model import Model, condition_grid, simulate_batch
from tests.envelope.loopback_cluster import LoopbackCluster

LEVELS = (0.56, 1.1, 1.7, 2.3)


def map_mix(n: int, seed: int = 0) -> np.ndarray:
    """``n`` landings drawn from a full map's conditions (every slope, speed and torque pair)."""
    slopes, speeds = np.arange(0.0, 61.0, 1.0), np.round(np.arange(0.5, 3.01, 0.1), 2)
    pairs = [(u, d) for u in LEVELS for d in LEVELS]
    full = np.concatenate(
        [condition_grid(slope_deg=slopes, speed=speeds, tau_up=u, tau_down=d) for u, d in pairs]
    )
    return full[np.random.default_rng(seed).choice(len(full), n, replace=False)]


def best_of(repeats: int, fn) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def local(grid: np.ndarray, model: Model, threads: int) -> None:
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        simulate_batch(grid, model)
    finally:
        numba.set_num_threads(before)


def sweep(grid: np.ndarray, model: Model, client) -> None:
    run_sweep(grid, model, client=client, progress=False)


def empty_task_overhead(client, model: Model, tasks: int) -> float:
    """Seconds per task of no landing, one worker thread busy with them back to back."""
    empty = condition_grid(slope_deg=0.0, speed=1.0)[:0]
    expected = fingerprint()
    t = time.perf_counter()
    futures = [client.submit(simulate_chunk, empty, model, expected, pure=False) for _ in range(tasks)]
    client.gather(futures)
    return (time.perf_counter() - t) / tasks


def fit_points(client, model: Model, points: int) -> float:
    from slopelander.ident.compare import state_ranges
    from slopelander.ident.fit import Evaluator, Problem, resolve_params
    from slopelander.ident.synth import NoiseModel, paper_drops, synthesize

    drops = synthesize(model, paper_drops(4, seed=1), NoiseModel(), duration=0.5)
    prob = Problem(model, drops, resolve_params(model), state_ranges(drops))
    us = [np.random.default_rng(k).uniform(0.3, 0.7, len(prob.params)) for k in range(points)]
    with Evaluator(prob, workers=1, client=client) as ev:
        ev.residuals(us[:1])  # the drops sent, the workers warm
        t = time.perf_counter()
        ev.residuals(us)
        return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--sizes", type=int, nargs="+", default=[32, 64, 128, 256, 512], help="grid sizes (landings)"
    )
    ap.add_argument("--repeats", type=int, default=2, help="runs of each configuration; the best is kept")
    ap.add_argument("--empty-tasks", type=int, default=200, help="tasks of no landing for the overhead")
    ap.add_argument(
        "--fit-points", type=int, default=16, help="parameter points of the fit section (0: skip)"
    )
    args = ap.parse_args()

    model = Model.default()
    warm_up(("batch", "landing"))
    print(
        f"{datetime.datetime.now():%Y-%m-%d %H:%M}, {os.cpu_count()} cores, slopelander {fingerprint()}, "
        f"load average {os.getloadavg()[0]:.2f} before the run"
    )
    grids = {n: map_mix(n, seed=n) for n in args.sizes}
    rows = {n: {} for n in args.sizes}
    t_fit = {}
    with LoopbackCluster(workers=1) as cluster:
        client = cluster.client
        run_sweep(grids[args.sizes[0]][:2], model, client=client, progress=False)  # checked and warm
        over_1w = empty_task_overhead(client, model, args.empty_tasks)
        for n, g in grids.items():
            rows[n]["here_1"] = best_of(args.repeats, lambda g=g: local(g, model, 1))
            rows[n]["here_all"] = best_of(args.repeats, lambda g=g: local(g, model, os.cpu_count() or 1))
            rows[n]["1w"] = best_of(
                args.repeats, lambda g=g: run_sweep(g, model, client=client, progress=False)
            )
        if args.fit_points:
            t_fit["1w"] = fit_points(client, model, args.fit_points)
        cluster.add_worker("w1")
        client.wait_for_workers(2, timeout=300)
        client.run(warm_up, ("batch", "landing"))  # the new worker's model loaded before the clock
        over_2w = empty_task_overhead(client, model, args.empty_tasks)
        for n, g in grids.items():
            rows[n]["2w"] = best_of(
                args.repeats, lambda g=g: run_sweep(g, model, client=client, progress=False)
            )
            rows[n]["here_1b"] = best_of(args.repeats, lambda g=g: local(g, model, 1))
        if args.fit_points:
            t_fit["2w"] = fit_points(client, model, args.fit_points)
            t_fit["here"] = fit_points(None, model, args.fit_points)

    print(
        "\n| landings | tasks (1 w / 2 w) | here, 1 thread | here, all cores | 1 worker | 2 workers "
        "| speed-up 1 -> 2 workers | overhead per task (1 worker) |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    per_task = []
    for n in args.sizes:
        r = rows[n]
        one = min(r["here_1"], r["here_1b"])  # the single-thread baseline, before and after
        t1, t2 = task_size(n, 1), task_size(n, 2)
        k1, k2 = -(-n // t1), -(-n // t2)
        over = (r["1w"] - one) / k1
        per_task.append(over)
        print(
            f"| {n} | {k1} / {k2} | {one:.3f} s | {r['here_all']:.3f} s | {r['1w']:.3f} s | {r['2w']:.3f} s "
            f"| {r['1w'] / r['2w']:.2f}x | {1000 * over:.1f} ms |"
        )
    n_max = args.sizes[-1]
    rate = n_max / min(rows[n_max]["here_1"], rows[n_max]["here_1b"])
    print(f"\none core here: {rate:.0f} landings/s (the {n_max}-landing grid on one thread)")
    print(
        f"a task of no landing, back to back: {1000 * over_1w:.1f} ms with 1 worker, "
        f"{1000 * over_2w:.1f} ms with 2 (submit, version check, result back)"
    )
    overhead = max(over_1w, float(np.median(per_task)))
    print(
        f"overhead per task taken as {1000 * overhead:.1f} ms (the larger of the empty tasks' and the "
        f"sweeps' median): a task of {max(1, round(19 * overhead * rate))} landings or more keeps it "
        f"under 5 % (tasks here: at least {task_size(1, 1)} landings)"
    )
    wins = [n for n in args.sizes if rows[n]["2w"] < rows[n]["1w"] * 0.95]
    if wins:
        print(f"2 workers beat 1 by more than 5 % from {wins[0]} landings on (the sizes measured)")
    else:
        print("2 workers never beat 1 by more than 5 % at the sizes measured")
    if t_fit:
        p = args.fit_points
        print(
            f"\nfit evaluations, {p} points x 4 drops of 0.5 s: here, one process {t_fit['here']:.2f} s; "
            f"1 worker {t_fit['1w']:.2f} s; 2 workers {t_fit['2w']:.2f} s "
            f"(speed-up 1 -> 2 workers {t_fit['1w'] / t_fit['2w']:.2f}x)"
        )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
