"""Torque ↔ current calibration: the shipped curve, the interpolation, file checks."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from slopelander.legs import CalibrationError, TorqueOutOfRange, load_calibration
from slopelander.legs.calibration import LegCurve, default_calibration_path

GOOD = """provenance: measured
units: {current: mA, torque: N*m}
legs:
""" + "".join(
    f"  - {{leg: {i}, current_ma: [0, 40, 100, 160], torque_nm: [0, 0, 1.5, 3.3]}}\n" for i in range(4)
)


def test_default_curve_is_shipped_and_marked_assumed():
    cal = load_calibration()
    assert cal.assumed and cal.provenance == "assumed"
    assert "PROVENANCE: ASSUMED" in default_calibration_path().read_text()
    for leg in range(4):
        curve = cal.legs[leg]
        assert curve.min_torque_nm == 0.0 and 3.1 <= curve.max_torque_nm <= 3.3
        for level in (0.56, 1.1, 1.7, 2.3):
            assert abs(cal.torque(leg, cal.current_for(leg, level)) - level) < 0.03


curve_points = st.lists(st.tuples(st.floats(0.1, 100), st.floats(0, 1)), min_size=2, max_size=12)


def build_curve(steps) -> LegCurve:
    currents, torques, c, t = [], [], 0.0, 0.0
    for dc, dt in steps:
        c += dc
        t += dt
        currents.append(c)
        torques.append(t)
    torques[-1] += 0.5  # rises somewhere
    return LegCurve(tuple(currents), tuple(torques))


@given(curve_points, st.floats(0, 1))
def test_inverse_is_monotone_and_round_trips(steps, fraction):
    curve = build_curve(steps)
    tau = curve.min_torque_nm + fraction * (curve.max_torque_nm - curve.min_torque_nm)
    current = curve.current_for(tau)
    assert curve.current_ma[0] <= current <= curve.current_ma[-1]
    assert curve.torque(current) == pytest.approx(tau, abs=1e-9)
    higher = curve.current_for(min(tau + 0.01, curve.max_torque_nm))
    assert higher >= current - 1e-9


@given(curve_points, st.floats(-10, 500), st.floats(-10, 500))
def test_torque_is_monotone_in_current(steps, a, b):
    curve = build_curve(steps)
    lo, hi = sorted((a, b))
    assert curve.torque(lo) <= curve.torque(hi)


def test_flat_stretch_inverts_to_where_the_curve_starts_rising():
    curve = LegCurve((0.0, 40.0, 100.0), (0.0, 0.0, 2.0))
    assert curve.current_for(0.0) == 40.0
    assert curve.current_for(1.0) == 70.0


def test_out_of_range_torque_names_leg_range_and_file(tmp_path):
    path = tmp_path / "cal.yaml"
    path.write_text(GOOD)
    cal = load_calibration(path)
    with pytest.raises(TorqueOutOfRange, match=r"leg 3: 3\.4 N·m .* 0–3\.3 N·m of .*cal\.yaml"):
        cal.current_for(3, 3.4)
    with pytest.raises(TorqueOutOfRange):
        cal.current_for(0, -0.5)
    assert cal.current_for(0, 1.5) == 100


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (("current_ma: [0, 40, 100, 160]", "current_ma: [0, 40, 40, 160]", 1), "legs[0].current_ma"),
        (("torque_nm: [0, 0, 1.5, 3.3]", "torque_nm: [0, 0, 1.5, 1.0]", 1), "legs[0].torque_nm"),
        (("torque_nm: [0, 0, 1.5, 3.3]", "torque_nm: [0, 1.5, 3.3]", 1), "legs[0].torque_nm"),
        (("torque_nm: [0, 0, 1.5, 3.3]", "torque_nm: [0, 0, .nan, 3.3]", 1), "legs[0].torque_nm"),
        (("units: {current: mA, torque: N*m}\n", "", 1), "units"),
        (("current: mA", "current: A", 1), "units.current"),
        (("torque: N*m", "torque: kgf", 1), "units.torque"),
        (("provenance: measured", "provenance: guessed", 1), "provenance"),
        (("{leg: 3,", "{leg: 2,", 1), "legs[3].leg"),
        (("  - {leg: 3, current_ma: [0, 40, 100, 160], torque_nm: [0, 0, 1.5, 3.3]}\n", "", 1), "legs"),
        (("provenance: measured\n", "provenance: measured\nboard_id: e661\n", 1), "board_id"),
        (("provenance: measured\n", "provenance: measured\nboard_id: board-of-bob-123\n", 1), "board_id"),
    ],
)
def test_bad_files_name_the_file_and_the_field(tmp_path, change, field):
    path = tmp_path / "bad.yaml"
    path.write_text(GOOD.replace(*change))
    with pytest.raises(CalibrationError) as err:
        load_calibration(path)
    assert err.value.field == field
    assert str(path) in str(err.value) and field in str(err.value)


def test_unreadable_and_malformed_files(tmp_path):
    with pytest.raises(CalibrationError, match="cannot read"):
        load_calibration(tmp_path / "missing.yaml")
    path = tmp_path / "broken.yaml"
    path.write_text("legs: [\n")
    with pytest.raises(CalibrationError, match="not valid YAML"):
        load_calibration(path)


def test_an_angle_range_narrows_the_angles_a_preset_may_ask_for(tmp_path):
    import yaml

    from slopelander.legs import AngleOutOfRange

    doc = yaml.safe_load(default_calibration_path().read_text())
    assert load_calibration().angle_range_deg == (0.0, 37.5)  # the protocol's range by default
    doc["angle_range_deg"] = [20, 37.5]
    path = tmp_path / "cal.yaml"
    path.write_text(yaml.safe_dump(doc))
    cal = load_calibration(path)
    cal.check_preset(1.1, 1.7, 25.0)
    with pytest.raises(AngleOutOfRange, match=r"leg 0: angle 18 deg is outside the range 20–37\.5 deg"):
        cal.check_preset(1.1, 1.7, 18)
    for bad in ([20], [30, 20], [0, 40], "20-30"):
        doc["angle_range_deg"] = bad
        path.write_text(yaml.safe_dump(doc))
        with pytest.raises(CalibrationError, match="angle_range_deg"):
            load_calibration(path)
