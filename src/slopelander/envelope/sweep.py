"""Run many landings: in chunks on this machine's cores, or on a Dask cluster.

Here, :func:`~slopelander.model.simulate_batch` spreads each chunk over every core, and the
chunks only pace the progress bar. On a Dask cluster a chunk is one task, run on one worker
thread (a cluster's threads are its cores; numba's own threads on top would oversubscribe
them), and the sweep is cut into several tasks per thread so that a slow or dying worker holds
back little, each still long enough that a task's overhead (a few ms, measured by
``benchmarks/dask_scaling.py``) is small next to its run time. Landings are independent, so the
result does not depend on where, in which chunks or in which order they ran: it is the same
array, bit for bit, as one batch here.

A task carries its chunk of conditions and the model (a few kB, code of user effects
included), and brings back one result row per landing. Workers are checked and warmed up
first (:mod:`slopelander.envelope.cluster`).
"""

from __future__ import annotations

import sys
from collections.abc import Iterator

import numpy as np

from slopelander.envelope.cluster import (
    ClusterError,
    check_worker,
    connect,
    fingerprint,
    gather,
    prepare,
    threads,
)
from slopelander.errors import SlopelanderError
from slopelander.model import RESULT_DTYPE, Model, simulate_batch

__all__ = ["DEFAULT_CHUNK", "ClusterError", "SweepError", "connect", "run_sweep", "task_size"]

DEFAULT_CHUNK = 1024
"""Landings per chunk: about one second of work, so the progress bar moves smoothly; on a
cluster, the most a task takes."""
TASKS_PER_THREAD = 4
"""On a cluster, a sweep is cut into at least this many tasks per worker thread, when it is
large enough: a worker that dies or lags holds back a fraction of its share, not all of it."""
MIN_TASK = 256
"""Fewest landings in a cluster task: about 0.2 s of one core's work (0.8 ms a landing), against
a task's overhead of 3-30 ms of CPU on loopback, 2-15 % (benchmarks/dask_scaling.py,
benchmarks/results/2026-12-06-dask-scaling.txt)."""


class SweepError(SlopelanderError):
    """A sweep could not run as asked (a bad chunk size); a cluster's failures are :class:`ClusterError`."""


def _chunks(n: int, chunk: int) -> Iterator[slice]:
    for start in range(0, n, chunk):
        yield slice(start, min(start + chunk, n))


def _progress_enabled(progress: bool | None) -> bool:
    if progress is None:
        return sys.stderr.isatty()
    return progress


def task_size(n: int, slots: int) -> int:
    """Landings per cluster task for a sweep of ``n`` on ``slots`` worker threads."""
    share = -(-n // (TASKS_PER_THREAD * max(1, slots)))
    return max(MIN_TASK, min(DEFAULT_CHUNK, share))


def run_sweep(
    grid: np.ndarray,
    model: Model,
    *,
    chunk: int | None = None,
    client=None,
    progress: bool | None = None,
    desc: str = "landings",
) -> np.ndarray:
    """Simulate every condition of ``grid`` (a CONDITION_DTYPE array) with ``model``.

    ``client`` is a ``distributed.Client`` (or a scheduler address) to run the chunks on a
    Dask cluster; ``None`` runs them here on every core. ``chunk``: landings per chunk (default
    :data:`DEFAULT_CHUNK` here, :func:`task_size` on a cluster). ``progress`` shows a tqdm bar
    over landings (``None``: only when stderr is a terminal). Returns RESULT_DTYPE rows in the
    order of ``grid``, the same whatever the chunks and wherever they ran.
    """
    if chunk is not None and chunk < 1:
        raise SweepError(f"chunk must be at least 1 landing, got {chunk}")
    n = len(grid)
    out = np.zeros(n, dtype=RESULT_DTYPE)
    if n == 0:
        return out
    from tqdm.auto import tqdm

    bar = tqdm(total=n, desc=desc, unit="landing", disable=not _progress_enabled(progress), smoothing=0.1)
    try:
        if client is None:
            for s in _chunks(n, chunk or DEFAULT_CHUNK):
                out[s] = simulate_batch(grid[s], model)
                bar.update(s.stop - s.start)
        else:
            _run_on_dask(grid, model, chunk, client, out, bar)
    finally:
        bar.close()
    return out


def simulate_chunk(conditions: np.ndarray, model: Model, expected: str) -> np.ndarray:
    """One cluster task: a chunk of landings on this worker thread, if this worker runs the
    client's slopelander (``expected``: its :func:`~slopelander.envelope.cluster.fingerprint`)."""
    import numba

    check_worker(expected)
    before = numba.get_num_threads()  # per thread in numba: other tasks keep theirs
    numba.set_num_threads(1)
    try:
        return simulate_batch(conditions, model)
    finally:
        numba.set_num_threads(before)


def _run_on_dask(grid: np.ndarray, model: Model, chunk: int | None, client, out: np.ndarray, bar) -> None:
    own = None
    if isinstance(client, str):
        client = own = connect(client)
    try:
        prepare(client, ("batch",))
        slices = list(_chunks(len(grid), chunk or task_size(len(grid), threads(client))))
        expected = fingerprint()
        futures = [client.submit(simulate_chunk, grid[s], model, expected, pure=False) for s in slices]

        def done(i: int, rows: np.ndarray) -> None:
            s = slices[i]
            out[s] = rows
            bar.update(s.stop - s.start)

        gather(futures, done)
    finally:
        if own is not None:
            own.close()
