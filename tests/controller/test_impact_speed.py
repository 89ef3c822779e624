"""The expected impact speed against the simulated vehicle's measured one (within 15 %).

On level ground the feet touch at a range of joint_z + L sin q = 0.15 m, 0.15 m below the 0.30 m
cut: after the cut latency and the thrust's decay the vehicle falls the rest, 1.63 m/s predicted.
The 35 deg roof, where the uphill foot touches just below the cut, is checked by tests/demo."""

from __future__ import annotations

import pytest

from slopelander.controller.config import load_config
from slopelander.controller.landing import contact_range, cut_dynamics, expected_impact_speed, leg_geometry
from slopelander.controller.link import mavlink
from slopelander.controller.runner import Lander
from slopelander.demo import Telemetry, first_contact_speed
from tests.controller.test_flight import airborne, wait  # noqa: F401 (the fixture)


def test_free_fall_from_the_cut_on_level_ground_matches_the_prediction(airborne):  # noqa: F811
    link, legs = airborne
    cfg = load_config()
    assert wait(link, link.request_stream(mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 50)) == "accepted"
    tele = Telemetry()
    link.add_listener(tele.listen)
    geom = leg_geometry()
    cut = cut_dynamics(cfg["reflex.cut_latency_s"])
    expected = expected_impact_speed(
        cfg["descent.rate_mps"], cfg["reflex.cut_height_m"], 0.0, geom, None, cut
    )
    assert contact_range(0.0, geom) == pytest.approx(0.152, abs=0.001)
    lander = Lander(link, cfg, (0.8, 1.5), legs=legs)
    assert lander.run(40) == "LANDED", lander.machine.history
    times = {h["to"]: h["t"] for h in lander.machine.history}
    measured = first_contact_speed(tele, times["ARMED"], times["LANDED"], cfg["reflex.impact_threshold_mps2"])
    assert measured is not None
    print(f"level ground: predicted {expected:.2f} m/s, measured {measured:.2f} m/s")
    assert measured == pytest.approx(expected, rel=0.15)
    assert measured > cfg["descent.rate_mps"] * 2  # it did fall freely after the cut
