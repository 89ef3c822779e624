"""Fits and ``diagnose`` on a real Dask cluster (a scheduler and two worker processes on
127.0.0.1): the same search, evaluation for evaluation, as one process, so the same numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
#: its tests share one loopback cluster (module fixtures): one worker runs them all
pytestmark = pytest.mark.xdist_group("ident/test_ident_cluster")

from slopelander.commands.diagnose import DIAGNOSE_EXIT  # noqa: E402
from slopelander.ident.compare import state_ranges  # noqa: E402
from slopelander.ident.fit import Evaluator, Identifier, Problem, resolve_params  # noqa: E402
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize  # noqa: E402
from tests.envelope.loopback_cluster import LoopbackCluster  # noqa: E402
from tests.ident.conftest import slopelander  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def cluster():
    with LoopbackCluster(workers=2) as c:
        yield c


def test_a_fit_on_two_worker_processes_is_the_one_process_fit(cluster, model):
    """Two parameters, CMA-ES then the least-squares polish (single points, whose drops are
    shared out between the workers, and Jacobian columns): bit for bit."""
    drops = synthesize(model, paper_drops(3, seed=2), NoiseModel(), duration=0.3)
    names = ["ground_stiffness", "friction_kinetic"]
    settings = {"cma_evals": 16, "ls_evals": 4, "seed": 1}
    here = Identifier(model, names, workers=1, **settings).fit(drops).result_
    with distributed.get_task_stream(cluster.client) as ts:
        there = Identifier(model, names, client=cluster.client, **settings).fit(drops).result_
    assert there.values == here.values
    assert there.u.tobytes() == here.u.tobytes()
    assert (there.cost, there.train_nrmse, there.nfev) == (here.cost, here.train_nrmse, here.nfev)
    assert there.ci95 == here.ci95 and there.warnings == here.warnings
    ran = [t for t in ts.data if t["key"].startswith("_dask_part")]
    assert len({t["worker"] for t in ran}) == 2, "both worker processes evaluated points"


def test_a_single_point_is_shared_out_and_joined_in_order(cluster, model):
    drops = synthesize(model, paper_drops(3, seed=2), NoiseModel(), duration=0.3)
    params = resolve_params(model, ["ground_stiffness", "friction_kinetic"])
    prob = Problem(model, drops, params, state_ranges(drops))
    points = [np.array([0.3, 0.6]), np.array([0.7, 0.2]), np.array([0.5, 0.5])]
    with Evaluator(prob, client=cluster.client) as ev:
        with distributed.get_task_stream(cluster.client) as ts:
            (one,) = ev.residuals(points[:1])
        many = ev.residuals(points)
    parts = [t for t in ts.data if t["key"].startswith("_dask_part")]
    assert len(parts) == 2, "one point: a part of its drops for each worker thread"
    assert one.tobytes() == prob.residuals(points[0]).tobytes()
    for got, u in zip(many, points, strict=True):
        assert got.tobytes() == prob.residuals(u).tobytes()


run = slopelander


def test_diagnose_with_a_user_effect_on_the_cluster_prints_what_one_process_prints(cluster, tmp_path):
    """The command as a user runs it, with a candidate from their own file (its compiled law
    travels to the workers with the model): the table and the verdict are the same."""
    ds = tmp_path / "ds"
    assert run("synth", "--out", str(ds), "--drops", "4", "--duration", "0.3", "--seed", "3").returncode == 0
    args = ["diagnose", str(ds), "--without", "leg_flex", "--fit", "ground_stiffness", "friction_kinetic"]
    args += ["--candidates", str(ROOT / "tests/ident/effects/ground_power.py"), "--refits", "2"]
    args += ["--cma-evals", "12", "--refit-evals", "8", "--ls-evals", "2", "--quiet"]
    here = run(*args, "--workers", "1")
    there = run(*args, "--dask", cluster.address)
    assert here.returncode in DIAGNOSE_EXIT.values() and "| rank | candidate |" in here.stdout, here.stderr
    assert (there.returncode, there.stdout) == (here.returncode, here.stdout)
