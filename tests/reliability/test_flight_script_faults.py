"""The on-board script absent, late or not answering, in flight (docs/failsafes.md, "Script
missing"): the companion's controller flies the simulated vehicle (real processes, lock-step),
whose script is left out or not run for a while (scenario fault ``script_stall``: the scheduler
skips it, its output overrides lapse, the messages for it wait in its queue)."""

from __future__ import annotations

import pytest

from slopelander.controller.runner import Lander
from slopelander_sitl.rig import Rig, config

LOITER = 5
PRESET = (1.7, 2.3)
CUT = {"cut_height_m": 0.45}
T0 = 30.0  # vehicle time the landing starts at, so a scenario fault can be placed in its descent
CENTRED = [{"t": 0.0, "channels": {3: 1500}}]  # the pilot holds the throttle centred (LOITER holds)


def hover_until(rig: Rig, t: float) -> None:
    rig.take_off(3.0)
    rig.go_over_roof(2.0)
    rig.set_legs(*PRESET)  # set before: the landing then reaches DESCEND at once
    assert rig.now < t - 0.5, f"the vehicle was not over the roof by {t} s ({rig.now:.1f} s)"
    rig.wait(t - rig.now)


def assert_hovering_safe(rig: Rig) -> None:
    rig.wait(1.0)
    assert rig.armed() and rig.mode() == LOITER, (rig.armed(), rig.mode())
    x = rig.track.pos[-1][1]
    assert rig.height() - rig.surface_z(x) > 0.5, rig.track.pos[-1]


def test_without_the_script_the_landing_is_refused_before_the_descent():
    with Rig(slope_deg=20.0, seed=21, scenario={"rc": CENTRED}, script=False) as rig:
        rig.take_off(3.0)
        rig.go_over_roof(2.0)
        lander = Lander(rig.link, config(reflex=CUT), PRESET, legs=rig.legs)
        assert lander.run(60.0) == "ABORTED"
        assert "on-board script not present" in lander.machine.history[-1]["reason"]
        assert "DESCEND" not in [h["to"] for h in lander.machine.history]
        assert not rig.track.event_times("EV_STOP")  # nothing was cut
        assert_hovering_safe(rig)


@pytest.mark.parametrize(
    ("stall_s", "ends"),
    [
        (0.5, "LANDED"),  # late: shorter than the 1 s the companion allows, the landing goes on
        (4.0, "ABORTED"),  # not answering: silent for 1 s of vehicle time in the descent
    ],
)
def test_a_script_that_stops_answering_in_the_descent(stall_s, ends):
    fault = {"kind": "script_stall", "start": T0 + 0.5, "end": T0 + 0.5 + stall_s}
    scenario = {"rc": CENTRED, "faults": [fault]}
    with Rig(slope_deg=20.0, seed=22, scenario=scenario) as rig:
        hover_until(rig, T0)
        lander = Lander(rig.link, config(reflex=CUT), PRESET, legs=rig.legs)
        end = lander.run(60.0)
        states = [h["to"] for h in lander.machine.history]
        assert end == ends, lander.machine.history
        if ends == "ABORTED":
            why = lander.machine.history[-1]
            assert why["reason"] == "on-board script silent" and why["from"] in ("DESCEND", "ARMED"), why
            # one second after the last announcement (5 Hz: up to 0.2 s before the stall began)
            assert T0 + 0.5 + 0.8 <= why["t"] <= T0 + 0.5 + 1.5, why
            assert not rig.track.event_times("EV_STOP", T0)  # no cut
            assert_hovering_safe(rig)
        else:
            assert "CUT" in states and "REVERSE" in states
