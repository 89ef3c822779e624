"""A rangefinder stuck in the descent, flown on both autopilots (the simulated vehicle and real
ArduCopter SITL, ``SLOPELANDER_ARDUCOPTER``): the landing is stopped in the air.

The soak on ArduCopter met a reading that held one value for 1.7-3 s in ARMED: the script never
cut, and the vehicle met the roof at 0.46 m/s with the motors running. Here the scenario's
``rangefinder_stuck`` holds the reading from a second after the landing begins (2.5 m over a flat
roof, before or early in the descent) for 8 s: the companion compares the range's change with the
descent LOCAL_POSITION_NED reports (controller/stuck_range.py) and aborts, a climb setpoint and
LOITER; the vehicle ends armed in LOITER clear of the roof, never having touched it."""

from __future__ import annotations

import pytest

from slopelander_sitl.rig import Rig, config
from tests.flights.test_landings_on_both_autopilots import roof_scenario

LOITER = 5
STUCK_T = 70.0  # vehicle time the reading sticks (s)
STUCK_S = 8.0
HOVER_OVER_ROOF_M = 2.5


def test_a_range_stuck_in_the_descent_stops_the_landing_in_the_air(autopilot: str) -> None:
    cfg = config()
    scenario = roof_scenario(autopilot)  # the pilot's throttle centred in the air: LOITER holds
    scenario["faults"] = [{"kind": "rangefinder_stuck", "start": STUCK_T, "end": STUCK_T + STUCK_S}]
    with Rig(slope_deg=0.0, seed=76, autopilot=autopilot, scenario=scenario) as rig:
        p, _ = rig.plan(cfg)
        rig.take_off(3.0)
        rig.go_over_roof(HOVER_OVER_ROOF_M)
        rig.set_legs(p.tau_up, p.tau_down)
        if rig.now > STUCK_T - 1.0:
            pytest.fail(f"the stuck range at {STUCK_T:g} s of vehicle time already began ({rig.now:.1f} s)")
        rig.wait(STUCK_T - 1.0 - rig.now)
        t_land = rig.now
        flight = rig.land((p.tau_up, p.tau_down), cfg, timeout_s=60.0, rest_s=2.0)
        rig.wait(3.0, tick=flight.lander.poll)
        x, z = rig.track.pos[-1][1], rig.track.pos[-1][2]
        low = min(q[2] - rig.surface_z(q[1]) for q in rig.track.pos if q[0] >= t_land)
        over, mode, armed = z - rig.surface_z(x), rig.mode(), rig.armed()
        contact = rig.track.contact(t_land)
    ctx = " | ".join([autopilot] + [f"{h['t']:.2f} {h['to']}: {h['reason']}" for h in flight.history])
    ctx += f" || lowest {low:.2f} m, now {over:.2f} m over the roof, mode {mode}, contact {contact}"
    print(ctx)
    assert flight.end == "ABORTED" and flight.history[-1]["reason"].startswith("range stuck"), ctx
    assert flight.time_of("ABORTED") - STUCK_T < STUCK_S, ctx  # judged while the reading was stuck
    assert contact is None and "CUT" not in [h["to"] for h in flight.history], ctx
    assert armed and mode == LOITER and over > 0.5, ctx
