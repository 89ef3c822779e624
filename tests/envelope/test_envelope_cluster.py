"""Maps and the lookup table on a real Dask cluster (a scheduler and two worker processes on
127.0.0.1): the same landings as one machine, bit for bit; a worker killed mid-sweep loses and
repeats nothing; a worker with another slopelander is refused."""

from __future__ import annotations

import os
import re
import signal
import threading
import time

import numpy as np
import pytest
import yaml

distributed = pytest.importorskip("distributed")
#: its tests share one loopback cluster (module fixtures): one worker runs them all
pytestmark = pytest.mark.xdist_group("envelope/test_envelope_cluster")

from slopelander.cli import main  # noqa: E402
from slopelander.envelope.cluster import ClusterError, ClusterVersionError, fingerprint, gather, prepare  # noqa: E402
from slopelander.envelope.sweep import run_sweep, simulate_chunk, task_size  # noqa: E402
from slopelander.model import simulate_batch  # noqa: E402
from tests.envelope.loopback_cluster import LoopbackCluster, other_slopelander  # noqa: E402


@pytest.fixture(scope="module")
def cluster():
    with LoopbackCluster(workers=2) as c:
        yield c


@pytest.fixture(scope="module")
def grid(tiny_axes):
    """20 cells x 4 torque pairs: 80 landings."""
    pairs = ((0.56, 1.1), (1.1, 2.3), (1.7, 1.7), (2.3, 0.56))
    return np.concatenate([tiny_axes.conditions(tau_up=u, tau_down=d) for u, d in pairs])


@pytest.fixture(scope="module")
def reference(grid, model):
    return simulate_batch(grid, model)


def same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.tobytes() == b.tobytes()  # NaN-aware, bit for bit


def test_a_sweep_on_two_worker_processes_is_the_one_machine_sweep(cluster, grid, model, reference):
    with distributed.get_task_stream(cluster.client) as ts:
        out = run_sweep(grid, model, chunk=10, client=cluster.client, progress=False)
    assert same(out, reference)
    ran = [t for t in ts.data if t["key"].startswith("simulate_chunk")]
    assert len(ran) == 8
    assert len({t["worker"] for t in ran}) == 2, "both worker processes took chunks"
    # by address too, the client made and closed on the way
    assert same(run_sweep(grid[:7], model, client=cluster.address, progress=False), reference[:7])


def test_sweeps_in_a_row_on_one_client_each_give_the_one_machine_sweep(cluster, grid, model, reference):
    """The same model in sweep after sweep on one client (nothing a sweep leaves on the cluster,
    or takes off it when done, is needed by the next)."""
    for chunk in (20, 20, None):
        assert same(run_sweep(grid, model, chunk=chunk, client=cluster.client, progress=False), reference)
    assert same(run_sweep(grid[::3], model, client=cluster.client, progress=False), reference[::3])


def test_the_table_command_on_the_cluster_writes_the_one_machine_table(cluster, tmp_path, capsys):
    grid = ["--slope-step", "15", "--speed-step", "0.8", "--speed-min", "0.6", "--quiet"]
    here, there = tmp_path / "here.yaml", tmp_path / "there.yaml"
    assert main(["table", "--out", str(here), *grid]) == 0
    assert main(["table", "--out", str(there), *grid, "--dask", cluster.address]) == 0
    a, b = yaml.safe_load(here.read_text()), yaml.safe_load(there.read_text())
    assert a["cells"]["outcome"] and a["cells"] == b["cells"] and a["axes"] == b["axes"]
    assert main(["table", "--out", str(there), *grid, "--dask", "tcp://127.0.0.1:9"]) == 1
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["asymmetric", "uncertainty"])
def test_the_map_command_on_the_cluster_writes_the_one_machine_map(cluster, tmp_path, kind):
    """The map as a user runs it, here and with --dask: every array of its .npz and its CSV the
    same (uncertainty: parameter sets drawn here, sent with the landings)."""
    grid = ["--slope-step", "15", "--speed-step", "0.8", "--speed-min", "0.6", "--quiet", "--sets", "2"]
    here, there = tmp_path / "here", tmp_path / "there"
    assert main(["map", kind, "--out", str(here), *grid]) == 0
    assert main(["map", kind, "--out", str(there), *grid, "--dask", cluster.address]) == 0
    data = sorted(p.name for p in here.iterdir() if p.suffix in (".npz", ".csv"))
    assert any(n.endswith(".npz") for n in data) and data == sorted(
        p.name for p in there.iterdir() if p.suffix in (".npz", ".csv")
    )
    for name in data:
        if name.endswith(".csv"):
            assert (here / name).read_text() == (there / name).read_text(), name
            continue
        with np.load(here / name) as a, np.load(there / name) as b:
            assert a.files and sorted(a.files) == sorted(b.files), name
            for key in a.files:
                assert same(a[key], b[key]), f"{name}: {key}"


def test_cluster_tasks_are_cut_to_amortise_their_overhead():
    assert task_size(100_000, 2) == 1024  # at most a chunk's worth
    assert task_size(4000, 2) == 500  # four tasks a worker thread
    assert task_size(300, 2) == 256  # never smaller than the overhead allows


def test_a_task_refuses_a_worker_with_another_slopelander(grid, model):
    with pytest.raises(ClusterVersionError, match=r"this process runs slopelander .* other sources"):
        simulate_chunk(grid[:1], model, fingerprint().split("+")[0] + "+000000000000")
    with pytest.raises(ClusterVersionError, match=r"runs slopelander \d.*, the client 9\.9"):
        simulate_chunk(grid[:1], model, "9.9+000000000000")


def test_a_cluster_of_another_slopelander_is_refused_with_its_versions(tmp_path, grid, model):
    path = other_slopelander(tmp_path, "0.0.0-other")
    with LoopbackCluster(workers=1, nanny=False, pythonpath=path) as other:
        (address,) = other.client.scheduler_info()["workers"]
        with pytest.raises(ClusterVersionError) as err:
            run_sweep(grid[:4], model, client=other.client, progress=False)
        text = str(err.value)
        assert address in text and "0.0.0-other" in text and fingerprint().split("+")[0] in text
        assert "install the same slopelander on every worker" in text
        # a worker that joins after the check is refused by each task it is given
        task = other.client.submit(simulate_chunk, grid[:1], model, fingerprint(), pure=False)
        with pytest.raises(ClusterVersionError, match=r"0\.0\.0-other"):
            task.result()


def test_a_scheduler_without_workers_is_an_error_not_a_wait_for_ever():
    with (
        LoopbackCluster(workers=0) as empty,
        pytest.raises(ClusterError, match=r"has no workers \(waited 1 s\): start them with 'dask worker tcp"),
    ):
        prepare(empty.client, ("batch",), wait=1.0)


def test_a_task_that_kills_its_workers_and_a_lost_scheduler_are_one_clear_error(grid, model):
    """Dask gives a task up after it killed ``allowed-failures`` workers (3 by default; 0 here,
    so one death is enough), and cancels the work when the scheduler goes."""
    env = {"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"}
    with LoopbackCluster(workers=1, nanny=False, scheduler_env=env) as c:
        assert same(
            run_sweep(grid[:2], model, client=c.client, progress=False), simulate_batch(grid[:2], model)
        )
        with pytest.raises(ClusterError, match="a task killed every worker it ran on"):
            gather([c.client.submit(os._exit, 3, pure=False)], lambda i, r: None)
        failed: dict[str, BaseException] = {}

        def sweep() -> None:  # no worker left: its tasks wait
            try:
                run_sweep(grid, model, client=c.client, progress=False)
            except ClusterError as exc:
                failed["error"] = exc

        waiting = threading.Thread(target=sweep)
        waiting.start()
        time.sleep(0.5)
        c.procs[0].kill()  # the scheduler (started by this test)
        waiting.join(timeout=60)
        assert not waiting.is_alive()
    assert "the Dask scheduler dropped the work" in str(failed["error"])
    assert "\n" not in str(failed["error"])


def test_a_worker_killed_mid_sweep_loses_and_repeats_nothing(cluster, grid, model, reference, capsys):
    """One worker process is killed (SIGKILL) while it runs a chunk: the scheduler runs its
    chunks again on the other worker (and on the one its nanny starts in its place); every
    landing is there, once, bit for bit."""
    client = cluster.client
    pids = cluster.worker_pids()
    big = np.concatenate([grid, grid])  # 160 landings in 20 chunks
    done: dict[str, np.ndarray] = {}
    sweep = threading.Thread(
        target=lambda: done.update(
            out=run_sweep(big, model, chunk=8, client=client, progress=True, desc="killed")
        )
    )
    sweep.start()
    victim, end = None, time.monotonic() + 120
    while victim is None and sweep.is_alive() and time.monotonic() < end:
        busy = [a for a, keys in client.processing().items() if any("simulate_chunk" in k for k in keys)]
        if busy:
            victim = busy[0]
            os.kill(pids[victim], signal.SIGKILL)
        else:
            time.sleep(0.02)
    assert victim is not None, "no worker was ever running a chunk"
    was_running = sweep.is_alive()
    sweep.join(timeout=300)
    assert not sweep.is_alive()
    assert was_running, "the sweep ended before the kill"
    assert same(done["out"], np.concatenate([reference, reference]))
    counts = [int(n) for n in re.findall(r"(\d+)/160\b", capsys.readouterr().err)]
    assert max(counts) == 160 and counts == sorted(counts), "each landing counted once"
    assert victim not in client.scheduler_info()["workers"]
    client.wait_for_workers(2, timeout=120)  # its nanny started another in its place
