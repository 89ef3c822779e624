"""Dask on this machine: the speed-up from 1 to 2 workers, a task's overhead, and the break-even.

    python3 benchmarks/dask_scaling.py                 # about 2-4 minutes on 2 cores
    python3 benchmarks/dask_scaling.py --sizes 256 1024 --rounds 3   # shorter

Starts a real ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1 (one thread each,
as docs/cluster.md advises) and measures, in the same run and on the same landings (a map's
mix: slopes 0-60 deg, speeds 0.5-3 m/s, the 16 torque-level pairs):

- the single-process baseline: ``simulate_batch`` on one thread and on every core;
- ``run_sweep`` on a cluster of 1 worker and on one of 2, for each grid size (its tasks cut
  as ``--dask`` cuts them); every configuration in turn within a round, the median of the
  rounds (and of the ratios within each round) printed;
- a task's overhead: many tasks of no landing through the same path (submit, the version
  check, the result back), and the same figure from the sweeps (cluster time less the
  single-thread time, over the tasks);
- fit evaluations (the residuals of parameter points over 8 drops of 2 s), one process vs the
  cluster, and on a worker left with the nanny's memory trimming (docs/cluster.md says why not).

From these it prints the smallest task worth sending (overhead under 5 %) and the grid size
from which 2 workers beat 1.
"""

from __future__ import annotations

import argparse
import datetime
import os
import statistics
import sys
import time
from pathlib import Path

import numba
import numpy as np
import psutil

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from slopelander.envelope.cluster import fingerprint, warm_up
from slopelander.envelope.sweep import run_sweep, simulate_chunk, task_size
from slopelander.model import Model, condition_grid, simulate_batch
from tests.envelope.loopback_cluster import LoopbackCluster

LEVELS = (0.56, 1.1, 1.7, 2.3)
IDLE_S = 4.0
"""Seconds the idle clusters are watched for the CPU they burn doing nothing."""
LATENCY_RUNS = 20
"""Sweeps of one landing that time a sweep's fixed cost."""
NO_TRIM = '{"MALLOC_TRIM_THRESHOLD_": None}'
"""The nanny's MALLOC_TRIM_THRESHOLD_=65536 also fixes glibc's mmap threshold at 128 KiB: every
residual vector of a fit is then mapped and unmapped (the fit section measures what it costs)."""


def map_mix(n: int, seed: int = 0) -> np.ndarray:
    """``n`` landings drawn from a full map's conditions (every slope, speed and torque pair)."""
    slopes, speeds = np.arange(0.0, 61.0, 1.0), np.round(np.arange(0.5, 3.01, 0.1), 2)
    pairs = [(u, d) for u in LEVELS for d in LEVELS]
    full = np.concatenate(
        [condition_grid(slope_deg=slopes, speed=speeds, tau_up=u, tau_down=d) for u, d in pairs]
    )
    return full[np.random.default_rng(seed).choice(len(full), n, replace=False)]


def cpu_seconds(pids: list[int]) -> float:
    """User + system CPU time of these processes so far (this one's every thread included)."""
    total = 0.0
    for pid in pids:
        try:
            t = psutil.Process(pid).cpu_times()
        except psutil.NoSuchProcess:
            continue
        total += t.user + t.system
    return total


def cluster_pids(cluster: LoopbackCluster) -> list[int]:
    """This process, the scheduler, the nannies and the workers: every process a task uses."""
    return [os.getpid(), *(p.pid for p in cluster.procs), *cluster.worker_pids().values()]


def timed(fn, pids: list[int]) -> tuple[float, float]:
    """(wall seconds, CPU seconds of ``pids``) of ``fn()``: on a machine shared with other work
    the CPU seconds hold still while the wall time moves with the load."""
    c, t = cpu_seconds(pids), time.perf_counter()
    fn()
    return time.perf_counter() - t, cpu_seconds(pids) - c


def local(grid: np.ndarray, model: Model, threads: int) -> None:
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        simulate_batch(grid, model)
    finally:
        numba.set_num_threads(before)


def wire(model: Model) -> None:
    """Print what a task carries, pickled as Dask pickles it."""
    import cloudpickle

    from slopelander.model import CONDITION_DTYPE, RESULT_DTYPE

    prob = fit_problem(model)
    residual = prob.residuals(np.full(len(prob.params), 0.5))
    print(
        f"over the wire: the model {len(cloudpickle.dumps(model)) / 1e3:.1f} kB, a landing's conditions "
        f"{CONDITION_DTYPE.itemsize} B, its result {RESULT_DTYPE.itemsize} B; a fit's drops and model "
        f"({FIT_DROPS} drops of {FIT_SECONDS:g} s) {len(cloudpickle.dumps(prob)) / 1e3:.0f} kB, "
        f"a point's residual vector {residual.nbytes / 1e3:.0f} kB"
    )


def sweep(grid: np.ndarray, model: Model, client) -> None:
    run_sweep(grid, model, client=client, progress=False)


def empty_tasks(client, model: Model, tasks: int) -> None:
    """``tasks`` tasks of no landing through a sweep's path, back to back."""
    empty = condition_grid(slope_deg=0.0, speed=1.0)[:0]
    expected = fingerprint()
    client.gather([client.submit(simulate_chunk, empty, model, expected, pure=False) for _ in range(tasks)])


FIT_DROPS, FIT_SECONDS = 8, 2.0


def fit_problem(model: Model):
    """Residuals over 8 drops of 2 s, the paper's seven parameters: a fit's unit of work."""
    from slopelander.ident.compare import state_ranges
    from slopelander.ident.fit import Problem, resolve_params
    from slopelander.ident.synth import NoiseModel, paper_drops, synthesize

    drops = synthesize(model, paper_drops(FIT_DROPS, seed=1), NoiseModel(), duration=FIT_SECONDS)
    return Problem(model, drops, resolve_params(model), state_ranges(drops))


def fit_points(client, prob, points: int, pids: list[int]) -> tuple[float, float]:
    """(wall, CPU) seconds to evaluate ``points`` parameter points (a CMA-ES generation)."""
    from slopelander.ident.fit import Evaluator

    us = [np.random.default_rng(k).uniform(0.3, 0.7, len(prob.params)) for k in range(points)]
    with Evaluator(prob, workers=1, client=client) as ev:
        ev.residuals(us[:1])  # the drops sent, the workers warm
        return timed(lambda: ev.residuals(us), pids)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 1024, 4096], help="landings")
    ap.add_argument("--rounds", type=int, default=5, help="rounds of every configuration in turn")
    ap.add_argument("--empty-tasks", type=int, default=200, help="tasks of no landing (overhead)")
    ap.add_argument("--fit-points", type=int, default=16, help="points of the fit section (0: skip)")
    args = ap.parse_args()

    model = Model.default()
    warm_up(("batch", "landing"))
    print(
        f"{datetime.datetime.now():%Y-%m-%d %H:%M}, {os.cpu_count()} cores, slopelander {fingerprint()}, "
        f"load average {os.getloadavg()[0]:.2f} before the run"
    )
    grids = {n: map_mix(n, seed=n) for n in args.sizes}
    wire(model)
    cores = os.cpu_count() or 1
    here = [os.getpid()]
    # both clusters up at once, used in turn: an idle worker costs nothing, and each round
    # measures every configuration within seconds of the others (this machine's speed moves)
    # the workers as docs/cluster.md starts them: glibc's own memory trimming, not the nanny's
    spawn = "DASK_DISTRIBUTED__NANNY__PRE_SPAWN_ENVIRON"
    print(f"workers started with {spawn}={NO_TRIM} (docs/cluster.md), but the one marked 'Dask's default'")
    # each process in its own session, as `dask worker` started from its own terminal or service
    with (
        LoopbackCluster(workers=1, sessions=True, worker_env={spawn: NO_TRIM}) as one,
        LoopbackCluster(workers=2, sessions=True, worker_env={spawn: NO_TRIM}) as two,
        LoopbackCluster(workers=1, sessions=True, worker_env={spawn: "{}"}) as default,
    ):
        for c in (one, two, default):
            c.client.run(warm_up, ("batch", "landing"))
            sweep(grids[args.sizes[0]][:2], model, c.client)  # checked and warm
        pids = {"1": cluster_pids(one), "2": cluster_pids(two)}
        # what an idle cluster burns (heartbeats, memory monitors): not a task's cost
        idle = {k: timed(lambda: time.sleep(IDLE_S), ps) for k, ps in pids.items()}
        idle_rate = {k: u / w for k, (w, u) in idle.items()}
        configs = {
            "here, 1 thread": (lambda g: local(g, model, 1), here),
            "here, all cores": (lambda g: local(g, model, cores), here),
            "1 worker": (lambda g: sweep(g, model, one.client), pids["1"]),
            "2 workers": (lambda g: sweep(g, model, two.client), pids["2"]),
        }
        runs = {(n, c): [] for n in args.sizes for c in configs}
        for _ in range(args.rounds):
            for n, g in grids.items():
                for c, (fn, ps) in configs.items():
                    runs[n, c].append(timed(lambda fn=fn, g=g: fn(g), ps))
        one_landing = grids[args.sizes[0]][:1]
        latency = [
            timed(lambda: sweep(one_landing, model, one.client), here)[0]
            - timed(lambda: local(one_landing, model, 1), here)[0]
            for _ in range(LATENCY_RUNS)
        ]
        empty = {
            k: timed(lambda c=c: empty_tasks(c.client, model, args.empty_tasks), pids[k])
            for k, c in (("1", one), ("2", two))
        }
        rss = [psutil.Process(pid).memory_info().rss for pid in two.worker_pids().values()]
        fits: dict[str, list[tuple[float, float]]] = {
            "here": [],
            "1 worker": [],
            "2 workers": [],
            "1 worker, Dask's default trim": [],
        }
        prob = fit_problem(model) if args.fit_points else None
        for _ in range(args.rounds if args.fit_points else 0):
            fits["here"].append(fit_points(None, prob, args.fit_points, here))
            fits["1 worker"].append(fit_points(one.client, prob, args.fit_points, pids["1"]))
            fits["2 workers"].append(fit_points(two.client, prob, args.fit_points, pids["2"]))
            fits["1 worker, Dask's default trim"].append(
                fit_points(default.client, prob, args.fit_points, cluster_pids(default))
            )

    med = statistics.median
    print(
        f"\nmedian of {args.rounds} rounds, each running every configuration in turn: wall seconds "
        "(CPU seconds of every process involved: this one, the scheduler, the nannies, the workers)"
    )
    print(
        "| landings | tasks (1 w / 2 w) | here, 1 thread | here, all cores | 1 worker | 2 workers "
        "| speed-up 1 -> 2 workers |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|")
    speedups, per_task = {}, []
    for n in args.sizes:
        wall = {c: [w for w, _ in runs[n, c]] for c in configs}
        cpu = {c: [u for _, u in runs[n, c]] for c in configs}
        k1, k2 = -(-n // task_size(n, 1)), -(-n // task_size(n, 2))
        speedups[n] = med([a / b for a, b in zip(wall["1 worker"], wall["2 workers"], strict=True)])
        beyond = [
            (w - idle_rate["1"] * t - h) / k1
            for h, w, t in zip(cpu["here, 1 thread"], cpu["1 worker"], wall["1 worker"], strict=True)
        ]
        per_task.append(med(beyond))
        cells = " | ".join(f"{med(wall[c]):.3f} ({med(cpu[c]):.3f})" for c in configs)
        print(f"| {n} | {k1} / {k2} | {cells} | {speedups[n]:.2f}x |")
    n_max = args.sizes[-1]
    rate = n_max / med([u for _, u in runs[n_max, "here, 1 thread"]])
    print(f"\none core here: {rate:.0f} landings per CPU second (the {n_max}-landing grid on one thread)")
    m = args.empty_tasks
    for k, r in idle_rate.items():
        print(f"an idle cluster of {k} worker(s) burns {1000 * r:.0f} ms CPU a second (heartbeats, monitors)")
    for k, (w, u) in empty.items():
        print(
            f"a task of no landing, {m} back to back on {k} worker(s): {1000 * w / m:.1f} ms wall, "
            f"{1000 * (u - idle_rate[k] * w) / m:.1f} ms CPU each beyond idling (submit, schedule, "
            "version check, result back)"
        )
    print(
        "a sweep's CPU per task beyond its landings and idling (1 worker less one thread here): "
        + ", ".join(f"{1000 * o:.0f} ms ({n} landings)" for n, o in zip(args.sizes, per_task, strict=True))
    )
    overhead = max((empty["1"][1] - idle_rate["1"] * empty["1"][0]) / m, med(per_task))
    print(
        f"taking {1000 * overhead:.0f} ms CPU a task (the larger of the two), a task of "
        f"{max(1, round(19 * overhead * rate))} landings or more keeps the overhead under 5 %; "
        f"--dask cuts at least {task_size(1, 1)}, at most {task_size(10**9, 1)} a task"
    )
    wins = [n for n in args.sizes if speedups[n] > 1.05]
    print(
        f"2 workers beat 1 (median wall speed-up over 1.05) from {wins[0]} landings on"
        if wins
        else "2 workers never beat 1 by more than 5 % at the sizes measured"
    )
    # break-even: from what grid size a cluster of W worker threads finishes a sweep sooner than
    # this machine, from this run's wall figures; this machine's cores counted as all free
    # (on a shared machine they are not: then the cluster wins sooner)
    fixed = med(latency)
    per_landing = med([t for t, _ in runs[n_max, "here, 1 thread"]]) / n_max
    all_cores = med([t for t, _ in runs[n_max, "here, all cores"]]) / n_max
    task_wall = empty["1"][0] / m
    print(
        f"\nbreak-even, from this run's wall figures: a sweep's fixed cost {1000 * fixed:.1f} ms (a sweep of "
        f"one landing on 1 worker less the same here, median of {LATENCY_RUNS}), a task "
        f"{1000 * task_wall:.1f} ms, a landing "
        f"{1000 * per_landing:.2f} ms on one thread (all {cores} cores here took "
        f"{all_cores / per_landing:.2f} of that: "
        f"{'other work held the other cores' if all_cores > 0.75 * per_landing else 'free cores'})"
    )
    sizes = np.unique(np.geomspace(8, 10**7, 400).astype(int))
    for threads_ in (2 * cores, 4 * cores, 8 * cores):

        def on_cluster(n: int, w: int = threads_) -> float:
            k = -(-n // task_size(n, w))
            return fixed + (n * per_landing + k * task_wall) / w

        beats = [int(n) for n in sizes if on_cluster(int(n)) < n * per_landing / cores]
        print(
            f"  {threads_} worker threads elsewhere beat this machine's {cores} free cores from about "
            f"{beats[0]} landings"
            if beats
            else f"  {threads_} worker threads never beat this machine's {cores} free cores"
        )
    if fits["here"]:
        p = args.fit_points
        f = {c: (med([w for w, _ in v]), med([u for _, u in v])) for c, v in fits.items()}
        up = med([a[0] / b[0] for a, b in zip(fits["1 worker"], fits["2 workers"], strict=True)])
        trim = med(
            [
                a[1] / b[1]
                for a, b in zip(fits["1 worker, Dask's default trim"], fits["1 worker"], strict=True)
            ]
        )
        print(
            f"\nfit evaluations, {p} points x {FIT_DROPS} drops of {FIT_SECONDS:g} s, wall (CPU) seconds, "
            f"median of {args.rounds}: "
            + "; ".join(f"{c} {w:.3f} ({u:.3f})" for c, (w, u) in f.items())
            + f"; speed-up 1 -> 2 workers {up:.2f}x"
        )
        print(
            f"a worker with Dask's default MALLOC_TRIM_THRESHOLD_=65536 spent {trim:.2f}x the CPU on them "
            "(median of the rounds' ratios)"
        )
    print(f"a worker process's memory after the sweeps: {', '.join(f'{r / 1e6:.0f} MB' for r in rss)}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
