"""The expected impact speed against the simulated vehicle's measured one (within 15 %).

On level ground the feet touch at a range of joint_z + L sin q = 0.15 m, 0.15 m below the 0.30 m
cut: after the cut latency and the thrust's decay the vehicle falls the rest, 1.45 m/s predicted.
The 35 deg roof, where the uphill foot touches just below the cut, is checked by tests/demo."""

from __future__ import annotations

import pytest

from slopelander.controller.config import load_config
from slopelander.controller.landing import contact_range, cut_dynamics, expected_impact_speed, leg_geometry
from slopelander.controller.telemetry import Telemetry, first_contact_speed
from slopelander_sitl.rig import Rig


def test_free_fall_from_the_cut_on_level_ground_matches_the_prediction():
    """Flown on the rig, lock-stepped (the vehicle's 50 Hz LOCAL_POSITION_NED and 200 Hz RAW_IMU,
    the legs on its clock); off the pad, over level ground."""
    cfg = load_config()
    with Rig(slope_deg=0.0, seed=1) as rig:
        tele = Telemetry()
        rig.link.add_listener(tele.listen)
        rig.take_off(2.7)  # the rangefinder reads up to 3 m
        flight = rig.land((0.8, 1.5), cfg, timeout_s=60.0, rest_s=0.5)
    geom = leg_geometry()
    cut = cut_dynamics(cfg["reflex.cut_latency_s"])
    expected = expected_impact_speed(
        cfg["descent.rate_mps"], cfg["reflex.cut_height_m"], 0.0, geom, None, cut
    )
    assert contact_range(0.0, geom) == pytest.approx(0.152, abs=0.001)
    assert flight.end == "LANDED", flight.history
    times = {h["to"]: h["t"] for h in flight.history}
    measured = first_contact_speed(tele, times["ARMED"], times["LANDED"], cfg["reflex.impact_threshold_mps2"])
    assert measured is not None
    print(f"level ground: predicted {expected:.2f} m/s, measured {measured:.2f} m/s")
    assert measured == pytest.approx(expected, rel=0.15)
    assert measured > cfg["descent.rate_mps"] * 2  # it did fall freely after the cut


def test_a_first_touch_under_the_spike_threshold_is_still_the_contact():
    """The telemetry's accelerometer samples a first touch at 19.8 m/s^2 from the hover's 1 g,
    under the 20 m/s^2 threshold (a foot on the roof under power: the script reverses at the
    harder contact 0.15 s later, or saw it in a sample the telemetry lacks). The speed is the one
    at the first touch, not at the second, with or without the script's time."""
    g = 9.80665
    tele = Telemetry()
    tele.t, tele.vz_up = [0.0, 0.02, 0.04], [-0.5, -0.5, -0.5]
    # 200 Hz: 1 g of hover, the first touch (19.8), free fall to 0 g, the second contact (45)
    series = [(0.05 + 0.005 * k, g) for k in range(4)]
    series += [(0.07, 19.8), (0.075, 12.0)] + [(0.08 + 0.005 * k, 0.0) for k in range(30)]
    series += [(0.23, 45.0), (0.235, 20.0)]
    tele.accel_t, tele.accel = [t for t, _ in series], [a for _, a in series]
    without = first_contact_speed(tele, 0.0, 1.0, 20.0)
    with_impact = first_contact_speed(tele, 0.0, 1.0, 20.0, t_impact=0.072)
    assert with_impact == pytest.approx(0.5, abs=1e-9)  # 1 g up to the touch: no speed gained
    assert without == with_impact
    tele.accel[4] = 12.0  # 1.22 g: under a foot's 1.3 g, and 2 g from the hover's floor of 1 g
    assert first_contact_speed(tele, 0.0, 1.0, 20.0) > 0.5 + g * 0.1  # the second contact
    # with a spike the script's time does not change the answer
    tele.accel[4] = 25.0
    assert first_contact_speed(tele, 0.0, 1.0, 20.0, 0.072) == first_contact_speed(tele, 0.0, 1.0, 20.0)


def test_a_soft_first_touch_after_the_free_fall_is_the_contact():
    """The script's rule: once the thrust has decayed, a reading 1 g above the lowest since the
    cut is the impact. A flat uphill leg's first touch reads 12.5 m/s^2 from 0.2 g of free fall;
    the downhill feet land 0.15 s later at 45 m/s^2: the speed is the first touch's."""
    g = 9.80665
    tele = Telemetry()
    tele.t, tele.vz_up = [0.0, 0.02, 0.04], [-0.5, -0.5, -0.5]
    series = [(0.05 + 0.005 * k, g) for k in range(4)]  # the thrust at the cut (0.05 s)
    series += [(0.07 + 0.005 * k, 0.2 * g) for k in range(6)]  # decayed: falling at 0.2 g
    # 12.5: 10.5 above the floor (the rule's 20 - g = 10.19), under a powered foot's 1.3 g
    series += [(0.10, 12.5), (0.105, 6.0)] + [(0.11 + 0.005 * k, 0.0) for k in range(24)]
    series += [(0.25, 45.0), (0.255, 20.0)]
    tele.accel_t, tele.accel = [t for t, _ in series], [a for _, a in series]
    soft = first_contact_speed(tele, 0.0, 1.0, 20.0, t_cut=0.05)
    assert soft == pytest.approx(0.5 + 0.8 * g * 0.03, abs=1e-9)  # 0.8 g of gain to 0.10 s
    tele.accel[10] = 11.0  # 1.12 g, 9.0 above the floor: under both rules, the second contact counts
    assert first_contact_speed(tele, 0.0, 1.0, 20.0, t_cut=0.05) > soft + g * 0.1
