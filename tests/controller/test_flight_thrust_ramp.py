"""42 deg at about 2.3 m/s, the outdoor campaign's landing 9 (real processes, lock-step): the reverse
thrust ends on evidence and ramps down over ``reflex.reverse_ramp_ms``, and the vehicle stays.

Ended as a step, the legs, bent under the thrust, spring back and let the feet go on this roof
(docs/model.md, "When the reverse thrust ends"); the ramp lets them hold. Flown with the
default configuration (1000 ms) and the table's preset and leg angles.
"""

from __future__ import annotations

import math

from slopelander.controller.landing import leg_geometry
from slopelander.controller.table import DEFAULT_TABLE, LookupTable
from slopelander_sitl.rig import Rig, config

SLOPE = 41.9
SPEED = 2.3  # m/s, the impact speed the cut height aims at
G = 9.80665


def cut_height(slope_deg: float, v: float) -> float:
    """Range at which the cut gives an impact at ``v`` from the 0.5 m/s descent (as the campaign)."""
    g = leg_geometry()
    a = math.radians(g.leg_angle_deg)
    contact = g.leg_length_m * math.cos(a) + (g.joint_x_m + g.leg_length_m * math.sin(a)) * math.tan(
        math.radians(slope_deg)
    )
    return round(contact + 0.06 + (v * v - 0.25) / (2 * G), 2)


def test_the_thrust_ramps_down_and_the_vehicle_stays_on_a_42_deg_roof():
    p = LookupTable.load(DEFAULT_TABLE).lookup(SLOPE, SPEED)
    cfg = config(reflex={"cut_height_m": cut_height(SLOPE, SPEED)})
    ramp = cfg["reflex.reverse_ramp_ms"] / 1000.0
    assert ramp >= 1.0  # the default the model shows holding (benchmarks/thrust_end.py)
    with Rig(slope_deg=SLOPE, seed=9) as rig:
        rig.take_off(3.0)
        rig.go_over_roof(2.0)
        op = rig.legs.start_angles(
            {0: p.angle_up_deg, 1: p.angle_up_deg, 2: p.angle_down_deg, 3: p.angle_down_deg}
        )
        rig.fly_until(lambda: op.done, 30.0, "set the leg angles")
        flight = rig.land((p.tau_up, p.tau_down), cfg, timeout_s=60.0, rest_s=2.0)
        c = flight.contact
        assert c is not None and c["vz"] > 1.5, c
        assert flight.end == "LANDED", flight.history
        assert flight.states[-3:] == ["REVERSE", "SETTLED", "LANDED"], flight.states
        ended = next(h for h in flight.history if h["to"] == "SETTLED")
        assert "still under reverse thrust" in ended["reason"], ended
        # the motors reach the stop band only once the ramp has run (not a command's latency after)
        stop = rig.track.event_times("EV_STOP", c["t"])
        assert stop and stop[0] - ended["t"] > 0.8 * ramp, (stop[:1], ended["t"])
        # disarmed at rest, and it stays where it rested for the 2 s watched after the landing
        landed = flight.history[-1]["t"]
        assert landed >= stop[0]
        after = [q for q in rig.track.pos if landed <= q[0] <= landed + 2.0]
        assert len(after) > 10
        assert math.dist(after[0][1:3], after[-1][1:3]) < 0.02, after[-3:]
        assert not rig.armed()
