"""The preset search: the paper's best-pair rule, the uphill angle rule, the continuous option."""

from __future__ import annotations

from itertools import product

import numpy as np
import pytest

from slopelander.envelope.presets import (
    STRATEGIES,
    TORQUE_LEVELS,
    TORQUE_RANGE,
    Strategy,
    StrategyError,
    choose_presets,
    linear_uphill_angle,
    preset_score,
)
from slopelander.model import RESULT_DTYPE, Outcome, condition_grid, simulate_batch

#: its tests share one small sweep (small_axes): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("envelope/envelope_presets")


def results(*rows: tuple[Outcome, float, float]) -> np.ndarray:
    r = np.zeros(len(rows), RESULT_DTYPE)
    for i, (o, cu, cd) in enumerate(rows):
        r[i]["outcome"], r[i]["compression_up"], r[i]["compression_down"] = float(o), cu, cd
    return r


def test_outcome_class_comes_before_compression():
    s = preset_score(
        results(
            (Outcome.IDEAL, 0.41, 0.0),
            (Outcome.UNDER_USED, 0.39, 0.39),
            (Outcome.END_OF_TRAVEL, 1.0, 0.0),
            (Outcome.SLID, 0.9, 0.9),
            (Outcome.JOINT_TOUCH, 0.5, 0.5),
            (Outcome.FLIP, 0.1, 0.1),
            (Outcome.DAMAGED, 0.0, 0.0),
        )
    )
    assert list(np.argsort(-s)) == [0, 1, 2, 3, 4, 5, 6]


def test_among_landings_that_stop_short_the_one_compressing_most_wins():
    s = preset_score(
        results(
            (Outcome.IDEAL, 0.5, 0.5),
            (Outcome.IDEAL, 0.9, 0.6),
            (Outcome.UNDER_USED, 0.1, 0.2),
            (Outcome.UNDER_USED, 0.3, 0.3),
        )
    )
    assert s[1] > s[0] and s[3] > s[2]


def test_among_end_of_travel_landings_the_softer_one_wins():
    s = preset_score(results((Outcome.END_OF_TRAVEL, 1.0, 0.9), (Outcome.END_OF_TRAVEL, 1.0, 0.3)))
    assert s[1] > s[0]


def test_uphill_angle_follows_the_papers_line_and_the_joint_range():
    a = linear_uphill_angle(np.array([0.0, 20.0, 40.0, 60.0, 200.0]), 0.5, 37.5)
    assert a.tolist() == pytest.approx([37.5, 30.75, 24.0, 17.25, 0.5])


def test_an_unknown_strategy_is_refused(model, tiny_axes):
    with pytest.raises(StrategyError, match="unknown strategy"):
        choose_presets(model, tiny_axes, "sideways")
    with pytest.raises(StrategyError):
        Strategy("x", angle="upside-down")


@pytest.fixture(scope="module")
def small_axes(tiny_axes):
    from slopelander.envelope.axes import MapAxes

    return MapAxes(tiny_axes.slopes[1:4], tiny_axes.speeds[1:3])  # 3 slopes x 2 speeds


def test_asymmetric_presets_are_the_best_of_all_16_pairs(model, small_axes):
    m = choose_presets(model, small_axes, "asymmetric", progress=False)
    assert m.meta["landings_simulated"] == small_axes.size * 16
    for i, s in enumerate(small_axes.slopes):
        for j, v in enumerate(small_axes.speeds):
            pairs = list(product(TORQUE_LEVELS, TORQUE_LEVELS))
            g = condition_grid(slope_deg=s, speed=v, tau_up=TORQUE_LEVELS, tau_down=TORQUE_LEVELS)
            res = simulate_batch(g, model)
            k = int(np.argmax(preset_score(res)))
            assert (m.fields["tau_up"][i, j], m.fields["tau_down"][i, j]) == pairs[k]
            assert m.outcome[i, j] == int(res["outcome"][k])


def test_the_continuous_option_is_never_worse_and_stays_in_range(model, small_axes):
    levels = choose_presets(model, small_axes, "asymmetric", progress=False)
    fine = choose_presets(
        model, small_axes, STRATEGIES["asymmetric"].with_options(refine=True), progress=False
    )

    def score(m):
        return preset_score(
            np.rec.fromarrays(
                [m.fields["outcome"], m.fields["compression_up"], m.fields["compression_down"]],
                names="outcome,compression_up,compression_down",
            )
        )

    assert np.all(score(fine) >= score(levels))
    for f in ("tau_up", "tau_down"):
        assert TORQUE_RANGE[0] <= fine.fields[f].min() and fine.fields[f].max() <= TORQUE_RANGE[1]


def test_rvt_map_flies_the_linear_uphill_angle_with_reverse_thrust(model, small_axes):
    m = choose_presets(model, small_axes, "rvt", progress=False)
    assert m.fields["angle_up_deg"][:, 0] == pytest.approx(linear_uphill_angle(small_axes.slopes))
    assert np.all(m.fields["angle_down_deg"] == 37.5)
    assert m.meta["strategy"]["reverse_percent"] == 100.0
    assert "reverse thrust" in m.meta["description"]


def test_rigid_gear_flies_the_locked_joint_model(model, small_axes):
    m = choose_presets(model, small_axes, "rigid", progress=False)
    assert "rigid_gear" in m.meta["model"]["effects"]
    assert m.meta["landings_simulated"] == small_axes.size


def test_a_strategy_may_end_its_reverse_thrust_and_says_so():
    from slopelander.envelope.presets import STRATEGIES, StrategyError

    held = STRATEGIES["rvt"]
    assert "reverse_duration" not in held.to_dict()  # held: the files read as before
    ended = held.with_options(reverse_duration=0.6, reverse_ramp=1.0)
    assert ended.to_dict()["reverse_duration"] == 0.6 and ended.to_dict()["reverse_ramp"] == 1.0
    assert "held 0.6 s, ramped to zero over 1 s" in ended.describe()
    # a strategy without reverse thrust has nothing to end: unchanged
    assert STRATEGIES["angle"].with_options(reverse_duration=0.6) == STRATEGIES["angle"]
    with pytest.raises(StrategyError, match="reverse_duration"):
        held.with_options(reverse_duration=-1.0)
    with pytest.raises(StrategyError, match="reverse_ramp"):
        held.with_options(reverse_duration=0.6, reverse_ramp=20.0)
