"""Chunked local sweeps give exactly the landings of one batch (on a Dask cluster:
test_envelope_cluster.py)."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander.envelope.cluster import ClusterError
from slopelander.envelope.sweep import SweepError, connect, run_sweep
from slopelander.model import simulate_batch

#: its tests share one grid and its reference (grid, reference): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("envelope/envelope_sweep")


@pytest.fixture(scope="module")
def grid(tiny_axes):
    g = tiny_axes.conditions(tau_up=1.1, tau_down=2.3)
    return g


@pytest.fixture(scope="module")
def reference(grid, model):
    return simulate_batch(grid, model)


def same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.tobytes() == b.tobytes()  # NaN-aware, bit for bit


def test_chunks_do_not_change_any_landing(grid, model, reference):
    assert same(run_sweep(grid, model, chunk=3, progress=False), reference)


def test_a_progress_bar_counts_every_landing(grid, model, reference, capsys):
    out = run_sweep(grid, model, chunk=7, progress=True, desc="probe")
    assert same(out, reference)
    err = capsys.readouterr().err
    assert f"{len(grid)}/{len(grid)}" in err and "probe" in err


def test_a_zero_chunk_is_refused(grid, model):
    with pytest.raises(SweepError, match="chunk"):
        run_sweep(grid, model, chunk=0)


def test_an_unreachable_scheduler_is_a_clear_error():
    pytest.importorskip("distributed")
    with pytest.raises(ClusterError, match="cannot reach"):
        connect("tcp://127.0.0.1:9", timeout="1s")
