"""Run many landings: in chunks on this machine's cores, or on a Dask cluster.

Work goes out in chunks of a few hundred to a few thousand landings, never one task per
landing: :func:`~slopelander.model.simulate_batch` already spreads a chunk over every local
core, and a chunk is large enough that a Dask task's overhead (~1 ms) is negligible next to
its run time (~1 s). Chunks are independent, so the result does not depend on where or in
which order they ran.

On a Dask cluster every worker imports :mod:`slopelander` itself, so it needs the same version
installed (``pip install slopelander[cluster]``); the model object is sent once per worker.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator

import numpy as np

from slopelander.errors import SlopelanderError
from slopelander.model import RESULT_DTYPE, Model, simulate_batch

DEFAULT_CHUNK = 1024
"""Landings per chunk: about one second of work, so the progress bar moves smoothly."""


class SweepError(SlopelanderError):
    """A sweep could not run (bad chunk size, unreachable Dask scheduler)."""


def _chunks(n: int, chunk: int) -> Iterator[slice]:
    for start in range(0, n, chunk):
        yield slice(start, min(start + chunk, n))


def _progress_enabled(progress: bool | None) -> bool:
    if progress is None:
        return sys.stderr.isatty()
    return progress


def connect(address: str, timeout: str = "10s"):
    """A Dask client for ``address`` (``tcp://host:8786``), or a clear error."""
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - the test extra installs it
        raise SweepError("--dask needs dask[distributed]: pip install 'slopelander[cluster]'") from None
    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        raise SweepError(f"cannot reach the Dask scheduler at {address}: {exc}") from None


def run_sweep(
    grid: np.ndarray,
    model: Model,
    *,
    chunk: int = DEFAULT_CHUNK,
    client=None,
    progress: bool | None = None,
    desc: str = "landings",
) -> np.ndarray:
    """Simulate every condition of ``grid`` (a CONDITION_DTYPE array) with ``model``.

    ``client`` is a ``distributed.Client`` (or a scheduler address) to run the chunks on a
    Dask cluster; ``None`` runs them here on every core. ``progress`` shows a tqdm bar over
    landings (``None``: only when stderr is a terminal). Returns RESULT_DTYPE rows in the
    order of ``grid``.
    """
    if chunk < 1:
        raise SweepError(f"chunk must be at least 1 landing, got {chunk}")
    n = len(grid)
    out = np.zeros(n, dtype=RESULT_DTYPE)
    if n == 0:
        return out
    from tqdm.auto import tqdm

    bar = tqdm(total=n, desc=desc, unit="landing", disable=not _progress_enabled(progress), smoothing=0.1)
    slices = list(_chunks(n, chunk))
    try:
        if client is None:
            for s in slices:
                out[s] = simulate_batch(grid[s], model)
                bar.update(s.stop - s.start)
        else:
            _run_on_dask(grid, model, slices, client, out, bar)
    finally:
        bar.close()
    return out


def _run_on_dask(grid: np.ndarray, model: Model, slices: list[slice], client, out: np.ndarray, bar) -> None:
    from distributed import as_completed

    own = None
    if isinstance(client, str):
        client = own = connect(client)
    try:
        model_future = client.scatter(model, broadcast=True)
        futures = {}
        for s in slices:
            f = client.submit(simulate_batch, grid[s], model_future, pure=False)
            futures[f] = s
        for f in as_completed(futures):
            s = futures[f]
            out[s] = f.result()
            bar.update(s.stop - s.start)
    finally:
        if own is not None:
            own.close()
