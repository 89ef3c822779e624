"""Controller settings, impact detector, expected impact speed and preset choice."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml

from slopelander.controller.config import ConfigError, RcPreset, load_config
from slopelander.controller.impact import G, ImpactDetector
from slopelander.controller.landing import (
    CUT_LATENCY_MAX_S,
    FOOT_MARGIN_M,
    CutDynamics,
    LegGeometry,
    PresetError,
    choose_preset,
    contact_range,
    expected_impact_speed,
    landing_cut_height,
    leg_geometry,
)
from slopelander.legs.calibration import load_calibration


def write(tmp_path, doc) -> Path:
    p = tmp_path / "c.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def test_defaults_load_and_override(tmp_path):
    cfg = load_config()
    assert cfg["reflex.cut_height_m"] == 0.30 and cfg.descent["rate_mps"] == 0.5
    cfg = load_config(write(tmp_path, {"reflex": {"cut_height_m": 0.4}}))
    assert cfg["reflex.cut_height_m"] == 0.4 and cfg["reflex.reverse_thrust_pct"] == 100


@pytest.mark.parametrize(
    ("doc", "field"),
    [
        ({"reflex": {"cut_height_m": 5.0}}, "reflex.cut_height_m"),
        ({"reflex": {"cut_height_m": "low"}}, "reflex.cut_height_m"),
        ({"reflex": {"cut_height_m": float("nan")}}, "reflex.cut_height_m"),
        ({"reflex": {"cut_heigth_m": 0.3}}, "reflex.cut_heigth_m"),
        ({"refelx": {}}, "refelx"),
        ({"link": {"command_retries": 1.5}}, "link.command_retries"),
        ({"reflex": {"arm_height_m": 0.25}}, "reflex.arm_height_m"),
        ({"reflex": {"reverse_ramp_ms": 3500}}, "reflex.reverse_ramp_ms"),
        ({"reflex": {"reverse_ramp_ms": 500.5}}, "reflex.reverse_ramp_ms"),
        ({"rc_presets": {"enabled": True}}, "rc_presets.presets"),
        (
            {
                "rc_presets": {
                    "presets": [{"min_us": 1000, "max_us": 1400, "tau_up_nm": 99, "tau_down_nm": 1}]
                }
            },
            "rc_presets.presets[0].tau_up_nm",
        ),
        (
            {
                "rc_presets": {
                    "presets": [
                        {"min_us": 1000, "max_us": 1600, "tau_up_nm": 1, "tau_down_nm": 1},
                        {"min_us": 1500, "max_us": 2000, "tau_up_nm": 1, "tau_down_nm": 1},
                    ]
                }
            },
            "rc_presets.presets",
        ),
    ],
)
def test_bad_settings_name_the_field(tmp_path, doc, field):
    with pytest.raises(ConfigError) as err:
        load_config(write(tmp_path, doc))
    assert err.value.field == field and field in str(err.value)


@pytest.mark.parametrize(
    ("doc", "field"),
    [
        ({"link": {"heartbeats_missed": 1}}, "link.heartbeats_missed"),  # one dropped frame is no loss
        ({"slope": {"survey_min_range_m": 0.2}}, "slope.survey_min_range_m"),  # below the foot's reach
        ({"slope": {"survey_speed_mps": 3.0}}, "slope.survey_speed_mps"),  # past the fixed look-ahead
    ],
)
def test_settings_that_leave_a_guard_blind_are_refused(tmp_path, doc, field):
    with pytest.raises(ConfigError) as err:
        load_config(write(tmp_path, doc))
    assert err.value.field == field


def test_the_survey_turns_back_above_the_uphill_foot_on_the_steepest_roof():
    """The floor of ``slope.survey_min_range_m`` is at least the range at which the uphill foot
    touches the steepest roof of the shipped table, at the table's uphill angle there."""
    from slopelander.controller.config import SURVEY_MIN_RANGE_FLOOR_M
    from slopelander.controller.landing import contact_range, leg_geometry
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable

    table = LookupTable.load(DEFAULT_TABLE)
    steepest = table.slope_range[1]
    angle = table.lookup(steepest, 0.5).angle_up_deg
    assert contact_range(steepest, leg_geometry(), angle) <= SURVEY_MIN_RANGE_FLOOR_M
    assert load_config()["slope.survey_min_range_m"] >= SURVEY_MIN_RANGE_FLOOR_M


def test_unreadable_and_not_yaml(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")
    p = tmp_path / "bad.yaml"
    p.write_text("reflex: [unclosed")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(p)


def test_impact_only_after_cut_first_large_sample_once():
    d = ImpactDetector(20.0)
    assert d.feed(1.0, 0, 0, -40.0) is None  # before the cut: hard manoeuvre, not an impact
    d.arm_after_cut(1.0)
    assert d.feed(1.005, 0, 0, -0.5) is None  # free fall
    assert d.feed(1.005, 0, 0, -50.0) is None  # repeated timestamp is ignored
    assert d.feed(1.010, float("nan"), 0, 0) is None
    assert d.feed(1.012, 0, 0, 60.0) is None  # 6 g down the body: a spike, not the roof pushing up
    hit = d.feed(1.015, 12.0, 0, -17.0)
    assert hit is not None and hit.t == 1.015 and hit.accel_mps2 == pytest.approx(math.hypot(12, 17))
    assert d.feed(1.020, 0, 0, -90.0) is None and d.impact == hit
    with pytest.raises(ValueError, match="above 1 g"):
        ImpactDetector(float("nan"))
    with pytest.raises(ValueError, match="above 1 g"):
        ImpactDetector(G)


def test_a_soft_contact_counts_from_the_lowest_reading_since_the_cut():
    """The thrust's 1 g at the cut decays: a contact that lifts the falling vehicle's reading by
    the threshold less 1 g is an impact once the thrust is gone (from RISE_AFTER_S, 50 ms, after
    the cut, as in the script), not while it and the rotors' vibration are still there."""
    d = ImpactDetector(20.0)
    d.arm_after_cut(1.0)
    assert d.feed(1.002, 0, 0, -G) is None  # the thrust at the cut
    assert d.feed(1.004, 0, 0, -G - 9.0) is None  # 1.9 g: under 2 g with the thrust still on
    d = ImpactDetector(20.0)
    d.arm_after_cut(1.0)
    for k, a in enumerate((G, 6.0, 3.0, 1.5, 1.0)):  # the thrust decays: free fall
        assert d.feed(1.002 + 0.005 * k, 0, 0, -a) is None
    assert d.feed(1.030, 0, 0, -11.4) is None  # 10.4 above the floor, but 30 ms after the cut
    assert d.feed(1.045, 0, 0, -11.0) is None  # 11.0 - 1.0 < 20 - g
    hit = d.feed(1.050, 3.0, 0, -11.0)  # |a| 11.4: 10.4 above the floor, 20 - g = 10.19
    assert hit is not None and hit.t == 1.050 and d.floor == 1.0
    d.reset()
    assert d.floor is None and d.impact is None


def test_impact_from_raw_imu_milli_g():
    from pymavlink.dialects.v20 import ardupilotmega as m

    d = ImpactDetector(20.0)
    d.arm_after_cut(0.5)
    assert d.feed_msg(m.MAVLink_raw_imu_message(600_000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)) is None
    hit = d.feed_msg(m.MAVLink_raw_imu_message(605_000, 0, 0, -3000, 0, 0, 0, 0, 0, 0))
    assert hit is not None and hit.accel_mps2 == pytest.approx(3 * G)


def test_expected_impact_speed():
    geom = leg_geometry()
    assert geom.leg_length_m == pytest.approx(0.201) and geom.leg_angle_deg == 37.5
    down = LegGeometry(0.2, 0.0, 90.0)  # a leg straight down (angle below the horizontal)
    # cut 0.3 m above with a 0.2 m leg: 0.1 m free fall from 0.5 m/s
    assert expected_impact_speed(0.5, 0.3, 0.0, down) == pytest.approx(math.sqrt(0.25 + 2 * G * 0.1))
    # cut below the foot: contact at the descent rate
    assert expected_impact_speed(0.5, 0.15, 0.0, down) == pytest.approx(0.5)
    # the joints below the centre of mass and the legs' angle: the model's 37.5 deg legs reach
    # 0.03 + 0.201 sin 37.5 = 0.152 m down on level ground, 0.299 m of range on a 35 deg slope
    assert contact_range(0.0, geom) == pytest.approx(0.03 + 0.201 * math.sin(math.radians(37.5)))
    assert contact_range(35.0, geom) == pytest.approx(0.299, abs=0.001)
    # the motors' stopping costs speed: a latency at the descent rate, then a decaying thrust
    slow = CutDynamics(latency_s=0.02, thrust_tau_s=0.025)
    free = expected_impact_speed(0.5, 0.3, 0.0, down)
    late = expected_impact_speed(0.5, 0.3, 0.0, down, cut=slow)
    assert 0.5 < late < free
    # a long fall: a free fall over d less what was covered at v_d for t_l + tau_T (and g tau_T^2 / 2)
    far = expected_impact_speed(0.5, 2.0, 0.0, down, cut=slow)
    lost = 0.5 * 0.045 + 0.5 * G * 0.025**2
    assert far == pytest.approx(math.sqrt(0.25 + 2 * G * (1.8 - lost)), rel=1e-6)
    # a slope brings the uphill ground closer: slower contact
    assert expected_impact_speed(0.5, 0.3, 35.0, geom) < expected_impact_speed(0.5, 0.3, 0.0, geom)
    with pytest.raises(ValueError, match="slope"):
        expected_impact_speed(0.5, 0.3, 95.0, geom)


def test_preset_choice_checked_against_calibration():
    cal = load_calibration()
    up, down, src = choose_preset(20, 1.0, None, RcPreset(1000, 1400, 0.8, 1.5), cal)
    assert (up, down) == (0.8, 1.5) and src == "pilot preset"
    with pytest.raises(PresetError, match="calibrated range"):
        choose_preset(20, 1.0, None, RcPreset(1000, 1400, 0.8, 9.0), cal)
    with pytest.raises(PresetError, match="nothing to set"):
        choose_preset(20, 1.0, None, None, cal)


def test_controller_modules_import_without_scipy_numba_matplotlib_model():
    src = Path(__file__).resolve().parents[2] / "src"
    code = textwrap.dedent(f"""
        import sys
        BLOCKED = ("scipy", "matplotlib", "numba", "slopelander.model", "slopelander.envelope",
                   "slopelander_sitl")
        class Block:
            def find_spec(self, name, path=None, target=None):
                if any(name == b or name.startswith(b + ".") for b in BLOCKED):
                    raise ImportError("blocked on the companion: " + name)
                return None
        sys.meta_path.insert(0, Block())
        sys.path.insert(0, {str(src)!r})
        from slopelander.controller import config, link, clock, impact, landing
        cfg = config.load_config()
        g = landing.leg_geometry()
        cut = landing.cut_dynamics(cfg["reflex.cut_latency_s"])
        print(landing.expected_impact_speed(0.5, cfg["reflex.cut_height_m"], 35.0, g, None, cut))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    # at 35 deg the uphill foot touches 1 mm below the 0.30 m cut, before the motors stop
    assert float(out.stdout) == 0.5


@pytest.mark.parametrize("slope_deg", [0.0, 10.0, 20.0, 30.0, 35.0, 40.0, 45.0, 50.0, 55.0, 60.0])
@pytest.mark.parametrize("angle", [None, 18.0, 25.0, 37.5])
def test_the_landing_cut_stops_the_motors_before_the_uphill_foot_touches(slope_deg, angle):
    """The configured 0.30 m stands where the uphill foot touches well below it; on a steep roof
    (or with the uphill leg low) the cut is raised so that the descent over the cut's longest
    latency still ends above the foot's contact range."""
    geom = leg_geometry()
    h = landing_cut_height(0.3, 0.5, slope_deg, geom, angle)
    touch = contact_range(slope_deg, geom, angle)
    assert h >= 0.3
    assert h - 0.5 * CUT_LATENCY_MAX_S > touch  # the motors stop before the foot meets the roof
    if touch + 0.5 * CUT_LATENCY_MAX_S + FOOT_MARGIN_M <= 0.3:
        assert h == 0.3  # not raised where it need not be
    else:
        assert h == pytest.approx(touch + 0.5 * CUT_LATENCY_MAX_S + FOOT_MARGIN_M, abs=1e-3)


def test_the_landing_plan_uses_the_tables_uphill_angle_and_tells_the_pilot_when_needed():
    from slopelander.controller.landing import angle_instruction, cut_dynamics, plan_landing
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable

    cal = load_calibration()
    table = LookupTable.load(DEFAULT_TABLE)
    geom = leg_geometry()
    cut = cut_dynamics(0.02)
    preset, speed = plan_landing(0.5, 0.3, 35.0, geom, table, None, cal, cut)
    assert preset.angle_up_deg == pytest.approx(table.lookup(35.0, speed).angle_up_deg)
    # the speed is the one for the table's angle, not for legs left at 37.5 deg, from the landing's
    # cut height: raised at 35 deg, where the uphill foot touches at a range of 0.28 m
    h = landing_cut_height(0.3, 0.5, 35.0, geom, preset.angle_up_deg)
    assert h > 0.3
    assert speed == pytest.approx(expected_impact_speed(0.5, h, 35.0, geom, preset.angle_up_deg, cut))
    assert speed != pytest.approx(expected_impact_speed(0.5, h, 35.0, geom, None, cut))
    todo = angle_instruction(preset.angle_up_deg, board_can_set=False)
    assert todo is not None and f"set the uphill legs to {preset.angle_up_deg:.1f} deg" in todo
    assert angle_instruction(preset.angle_up_deg, board_can_set=True) is None
    pilot, _ = plan_landing(0.5, 0.3, 35.0, geom, table, RcPreset(1000, 1400, 0.8, 1.5), cal, cut)
    assert pilot.angle_up_deg is None and angle_instruction(None, board_can_set=False) is None
    with pytest.raises(PresetError, match="outside the range"):
        cal_narrow = type(cal)(cal.legs, cal.provenance, "narrow.yaml", (30.0, 37.5))
        plan_landing(0.5, 0.3, 35.0, geom, table, None, cal_narrow, cut)
