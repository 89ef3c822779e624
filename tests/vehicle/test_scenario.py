"""Scenario files: defaults, clear errors naming the field, deterministic faults."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander_sitl.vehicle.params import ParamError, load_parm
from slopelander_sitl.vehicle.scenario import ScenarioError, load_scenario, scenario_from_dict
from slopelander_sitl.vehicle.sensors import Range


@pytest.mark.parametrize(
    ("data", "field"),
    [
        ({"slope": 20}, "unknown field"),
        ({"slope_deg": "steep"}, "slope_deg"),
        ({"slope_deg": 80}, "slope_deg"),
        ({"seed": -1}, "seed"),
        ({"start_on": "tree"}, "start_on"),
        ({"rc": [{"t": 1, "channels": {3: 5000}}]}, "rc[0].channels.3"),
        ({"rc": [{"t": 2, "channels": {3: 1500}}, {"t": 1, "channels": {3: 1000}}]}, "rc[1].t"),
        ({"faults": [{"kind": "gremlin", "start": 0, "end": 1}]}, "faults[0].kind"),
        ({"faults": [{"kind": "imu_spike", "start": 2, "end": 1}]}, "faults[0].end"),
        ({"model_params": {"no_such_parameter": 1.0}}, "model_params"),
        ({"wind": 3}, "wind must be a mapping"),
        ({"wind": {"gust": []}}, "wind: unknown field"),
        ({"wind": {"steady": {"fx_n": "strong"}}}, "wind.steady.fx_n"),
        ({"wind": {"steady": {"fx_n": 500}}}, "wind.steady.fx_n"),
        ({"wind": {"gusts": [{"t_s": 1, "duration_s": 2, "fx_n": 3, "fy_n": 1}]}}, "wind.gusts[0]"),
        (
            {"wind": {"gusts": [{"t_s": 1, "duration_s": 2}, {"t_s": 1, "duration_s": 0}]}},
            "wind.gusts[1].duration_s",
        ),
        ({"wind": {"gusts": [{"t_s": -1, "duration_s": 2}]}}, "wind.gusts[0].t_s"),
        ({"wind": {"random_gusts": {"count": 2.5, "max_n": 3}}}, "wind.random_gusts.count"),
        ({"wind": {"random_gusts": {"count": 2, "max_n": -3}}}, "wind.random_gusts.max_n"),
        (
            {"wind": {"random_gusts": {"count": 2, "max_n": 3, "from_s": 5, "to_s": 1}}},
            "wind.random_gusts.to_s",
        ),
    ],
)
def test_bad_scenarios_name_the_field(data, field):
    with pytest.raises(ScenarioError, match=field.replace("[", r"\[").replace("]", r"\]")):
        scenario_from_dict(data, "s.yaml")


def test_file_errors_name_the_file(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("slope_deg: [1, 2\n")
    with pytest.raises(ScenarioError, match=r"bad\.yaml"):
        load_scenario(p)
    with pytest.raises(ScenarioError, match=r"missing\.yaml"):
        load_scenario(tmp_path / "missing.yaml")


def test_rc_timeline_and_defaults():
    s = scenario_from_dict({"rc": [{"t": 1.0, "channels": {3: 1500}}, {"t": 2.0, "channels": {2: 1400}}]})
    assert s.rc_at(3, 0.5) == 1000  # throttle low before the first event
    assert s.rc_at(3, 1.5) == 1500
    assert s.rc_at(2, 1.5) == 1500
    assert s.rc_at(2, 2.5) == 1400
    assert s.rc_at(3, 2.5) == 1500


def test_range_faults_are_deterministic_from_the_seed():
    faults = [
        {"kind": "rangefinder_dropout", "start": 1.0, "end": 2.0},
        {"kind": "rangefinder_stuck", "start": 3.0, "end": 4.0},
        {"kind": "rangefinder_spike", "start": 5.0, "end": 6.0, "value": 0.1},
    ]
    good = Range(1.0, 4, 100)

    def run(seed: int) -> list[float]:
        s = scenario_from_dict({"seed": seed, "faults": faults})
        rng = np.random.default_rng(s.seed)
        out = []
        for i in range(700):
            t = i / 100
            out.append(s.range_fault(t, Range(good.distance_m + t, 4, 100), rng))
        return out

    a, b, c = run(3), run(3), run(4)
    assert [r.distance_m for r in a] == [r.distance_m for r in b]
    assert [r.distance_m for r in a] != [r.distance_m for r in c]
    assert a[150].status == 1  # dropout: NoData
    assert a[350].distance_m == a[300].distance_m  # stuck at the reading when it began
    assert a[550].distance_m == 0.1  # spike
    assert a[650].status == 4 and abs(a[650].distance_m - 7.5) < 0.05


def test_a_range_fault_below_a_height_acts_only_there():
    s = scenario_from_dict(
        {"faults": [{"kind": "rangefinder_dropout", "start": 0, "end": 99, "below_m": 0.35}]}
    )
    rng = np.random.default_rng(0)
    assert s.range_fault(1.0, Range(0.5, 4, 100), rng).status == 4
    assert s.range_fault(1.0, Range(0.3, 4, 100), rng).status == 1
    with pytest.raises(ScenarioError, match="rangefinder faults only"):
        scenario_from_dict({"faults": [{"kind": "imu_spike", "start": 0, "end": 1, "below_m": 0.35}]})
    with pytest.raises(ScenarioError, match="below_m"):
        scenario_from_dict({"faults": [{"kind": "rangefinder_dropout", "start": 0, "end": 1, "below_m": -1}]})


def test_parm_file_errors_name_file_and_line(tmp_path):
    p = tmp_path / "x.parm"
    p.write_text("FRAME_CLASS 1\nMOT_PWM_MIN fast\n")
    with pytest.raises(ParamError, match=r"x.parm:2: MOT_PWM_MIN"):
        load_parm(p)
    p.write_text("# comment\nFRAME_CLASS,1\n\nMOT_PWM_MIN 1525 # route A\n")
    assert load_parm(p) == {"FRAME_CLASS": 1.0, "MOT_PWM_MIN": 1525.0}


def test_wind_gusts_have_a_1_minus_cos_shape_and_add_to_the_steady_force():
    s = scenario_from_dict(
        {"wind": {"steady": {"fx_n": 0.5}, "gusts": [{"t_s": 10, "duration_s": 2, "fx_n": 3, "fz_n": -1}]}}
    )
    w = s.wind
    assert w.force_at(9.99) == (0.5, 0.0)
    assert w.force_at(10.5) == pytest.approx((0.5 + 1.5, -0.5))  # a quarter in: half the peak
    assert w.force_at(11.0) == pytest.approx((3.5, -1.0))  # peak at mid-time
    assert w.force_at(12.0) == (0.5, 0.0)
    assert scenario_from_dict({}).wind.calm


def test_random_gusts_are_deterministic_from_the_seed_and_within_bounds():
    wind = {"random_gusts": {"count": 20, "max_n": 4.0, "from_s": 5, "to_s": 50, "duration_s": 1.5}}
    a = scenario_from_dict({"seed": 3, "wind": wind}).wind.gusts
    b = scenario_from_dict({"seed": 3, "wind": wind}).wind.gusts
    c = scenario_from_dict({"seed": 4, "wind": wind}).wind.gusts
    assert a == b and a != c and len(a) == 20
    assert all(5 <= g.t_s < 50 and abs(g.fx_n) <= 4.0 and g.fz_n == 0 and g.duration_s == 1.5 for g in a)
    assert max(abs(g.fx_n) for g in a) > 2.0  # drawn over the range, not all near zero
    assert [g.t_s for g in a] == sorted(g.t_s for g in a)
