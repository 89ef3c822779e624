"""The fit's global search is an object: the shipped two find the truth, a user's own is used."""

from dataclasses import dataclass, field

import numpy as np
import pytest

from slopelander.ident.fit import FitError, Identifier
from slopelander.ident.optimizers import CMA, DifferentialEvolution, SearchTask, optimizer_named
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize
from tests.ident.conftest import slopelander

#: its tests share the drops (a module fixture): one worker runs them
pytestmark = pytest.mark.xdist_group("ident/test_optimizers")

NAMES = ["ground_stiffness", "friction_kinetic"]


@pytest.fixture(scope="module")
def drops(model):
    truth = model.with_params(ground_stiffness=3.0e4, friction_kinetic=0.65)
    return synthesize(truth, paper_drops(3, seed=4), NoiseModel.none(), duration=0.3)


def test_differential_evolution_finds_the_truth_within_its_budget(model, drops):
    """From the model's values (k_g 2.17e4, mu_k 0.8) to the truth (3e4, 0.65), scipy's
    differential evolution in place of CMA-ES, then the same polish."""
    ident = Identifier(model, NAMES, cma_evals=120, ls_evals=20, workers=1, optimizer=DifferentialEvolution())
    r = ident.fit(drops).result_
    assert r.values["ground_stiffness"] == pytest.approx(3.0e4, rel=0.03)
    assert r.values["friction_kinetic"] == pytest.approx(0.65, rel=0.03)
    assert r.cost < r.start_cost
    # the start, 120 of the search (12 generations of 10), the polish's points and Jacobians
    assert 121 <= r.nfev <= 121 + 20 * 3


@dataclass
class GridSearch:
    """A user's own global search: a fixed grid over the cube, one batch."""

    side: int = 5
    name: str = "grid"
    asked: list = field(default_factory=list)

    def search(self, task: SearchTask) -> None:
        g = np.linspace(0.0, 1.0, self.side)
        points = [np.array([a, b]) for a in g for b in g][: task.budget]
        self.asked.append(len(points))
        task.costs(points)


def test_a_users_optimizer_is_used_and_its_best_point_kept(model, drops):
    grid = GridSearch()
    r = Identifier(model, NAMES, cma_evals=25, ls_evals=0, workers=1, optimizer=grid).fit(drops).result_
    assert grid.asked == [25]
    # no polish: the result is the best grid point (or the start), evaluated here again
    g = np.linspace(0.0, 1.0, 5)
    assert r.cost <= r.start_cost
    assert r.u.tolist() in [[a, b] for a in g for b in g] or r.cost == r.start_cost
    # the start, the grid, the point, and its interval Jacobian's central differences (2 per parameter)
    assert r.nfev == 1 + 25 + 1 + 2 * 2


def test_the_default_is_cma_and_a_wrong_optimizer_is_refused_before_any_work(model, drops):
    assert isinstance(optimizer_named("cma"), CMA) and isinstance(
        optimizer_named("de"), DifferentialEvolution
    )
    with pytest.raises(ValueError, match="choose one of cma, de"):
        optimizer_named("nelder")
    with pytest.raises(FitError, match="search\\(task\\) method"):
        Identifier(model, NAMES, optimizer="cma").fit(drops)  # type: ignore[arg-type]


def test_the_command_takes_the_optimizer_by_name(tmp_path):
    run = slopelander
    ds = tmp_path / "ds"
    assert run("synth", "--out", str(ds), "--drops", "3", "--duration", "0.3", "--seed", "4").returncode == 0
    common = ("fit", str(ds), "--fit", "friction_kinetic", "--repeats", "1", "--workers", "1", "--quiet")
    r = run(*common, "--optimizer", "de", "--cma-evals", "30", "--ls-evals", "3")
    assert r.returncode == 0, r.stderr
    assert "| friction_kinetic |" in r.stdout
    bad = run(*common, "--optimizer", "nelder")
    assert bad.returncode == 2 and "invalid choice: 'nelder'" in bad.stderr


def _bowl(centre: float):
    def evaluate(points):
        return [float(np.sum((np.asarray(p) - centre) ** 2)) for p in points]

    return evaluate


def _task(evaluate, x0: np.ndarray, budget: int) -> SearchTask:
    cost = _bowl(0.3)([x0])[0]  # the start's, evaluated before the search (as a fit does)
    return SearchTask(evaluate, [x0], budget, seed=0, sigma=0.25, best_u=x0, best_cost=cost)


def test_a_stalled_cma_search_stops_and_one_that_improves_runs_on():
    """Started at the optimum, no generation finds a lower cost: with ``stall`` 8 the run ends
    after 8 generations instead of spending its budget; started away from it, every generation
    improves and the search runs on to the optimum."""
    evals = []

    def counted(points):
        evals.append(len(points))
        return _bowl(0.3)(points)

    at = np.full(6, 0.3)
    CMA(stall=8).search(_task(counted, at, 400))
    assert sum(evals) == 8 * CMA().population(6)
    evals.clear()
    CMA().search(_task(counted, at, 400))
    assert sum(evals) >= 390  # without stall: the budget, less a part generation
    evals.clear()
    away = _task(counted, np.full(6, 0.8), 400)
    CMA(stall=8).search(away)
    assert away.best_cost < 0.01 and sum(evals) >= 390
