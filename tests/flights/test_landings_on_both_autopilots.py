"""The landings that matter, flown on both autopilots with the same assertions: the project's
simulated vehicle (``sitl.vehicle``) and real ArduCopter SITL (V4.7-dev, ``SLOPELANDER_ARDUCOPTER``)
behind the same physics, leg board and companion.

Each flight: take off from the pad, fly over the roof, land with the lookup table's preset for the
slope and the expected impact speed, the cut height set for the slope (the uphill foot's contact
range plus a 0.1 m fall). A landing ends when the autopilot's HEARTBEAT says disarmed: a command
sent is not an end.

Which cases fly on both (CI stays well under 30 minutes on 2 cores: one ArduCopter flight is
about a minute of wall time, its boot and EKF start included): pad → roof at 0°, 20°, 35° and
45°, and 55° with reverse thrust. The pilot's RC preset switch, the link cut in DESCEND and in
REVERSE and the unplugged leg board fly on the simulated vehicle only for now
(tests/controller/test_flight_safety.py, tests/reliability/): they are next to move here.
"""

from __future__ import annotations

import math

import pytest

from sitl.rig import Rig, config
from slopelander.controller.landing import expected_impact_speed, leg_geometry
from slopelander.controller.table import DEFAULT_TABLE, LookupTable

# each landing flies a vehicle of its own: the workers may share the landings out (the flights on
# ArduCopter still one at a time: tests/flights/conftest.py)
pytestmark = pytest.mark.spread

FALL_M = 0.1


def contact_range(slope_deg: float) -> float:
    """Range (m) at which the uphill foot of a level vehicle touches (controller/landing.py geometry)."""
    g = leg_geometry()
    a = math.radians(g.leg_angle_deg)
    return g.leg_length_m * math.cos(a) + (g.joint_x_m + g.leg_length_m * math.sin(a)) * math.tan(
        math.radians(slope_deg)
    )


def fly_one_landing(autopilot: str, slope_deg: float, **reflex):
    cut = round(max(0.3, contact_range(slope_deg) + FALL_M), 2)
    cfg = config(reflex={"cut_height_m": cut, **reflex})
    speed = expected_impact_speed(cfg["descent.rate_mps"], cut, slope_deg, leg_geometry())
    p = LookupTable.load(DEFAULT_TABLE).lookup(slope_deg, speed)
    with Rig(slope_deg=slope_deg, seed=int(slope_deg) + 1, autopilot=autopilot) as rig:
        rig.take_off(3.0)
        rig.go_over_roof(2.5)
        flight = rig.land((p.tau_up, p.tau_down), cfg, timeout_s=90.0, rest_s=3.0)
        armed_at_end = rig.armed()
        statustext = list(rig.link.statustext)
    return flight, armed_at_end, statustext, p


@pytest.mark.parametrize("slope_deg", [0.0, 20.0, 35.0, 45.0])
def test_pad_to_roof_lands_and_ends_disarmed(autopilot: str, slope_deg: float) -> None:
    flight, armed, texts, preset = fly_one_landing(autopilot, slope_deg)
    ctx = " | ".join(
        [f"{autopilot} {slope_deg:g} deg"] + [f"{h['to']}: {h['reason']}" for h in flight.history]
    )
    ctx += " || " + " | ".join(texts[-8:])
    assert flight.end == "LANDED", ctx
    assert not armed, ctx  # the autopilot's own HEARTBEAT, after the landing ended
    c = flight.contact
    assert c is not None, ctx
    stops = flight.track.event_times("EV_STOP", flight.t_start)
    assert stops and stops[0] < c["t"], (stops, c)  # the motors were stopped before the feet met the roof
    rvt = flight.track.event_times("EV_RVT", c["t"] - 0.001)
    assert rvt and rvt[0] - c["t"] < 0.03, (rvt, c)  # reverse thrust within 30 ms of contact
    outcome, figures = flight.classify(slope_deg, until=flight.time_of("LANDED"))
    assert outcome == "landed", (ctx, figures, preset)
