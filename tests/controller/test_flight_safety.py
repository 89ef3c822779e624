"""Aborts and the failure rows of docs/failsafes.md that need a real flight on the simulated
vehicle alone: the companion's controller against the simulated vehicle and leg board (real
processes, lock-step). The pilot's preset switch, a link lost in the descent and the leg board
unplugged fly on both autopilots (tests/flights/test_landings_on_both_autopilots.py).

One vehicle on a 20 deg roof flies every test in this module, in order. The scenario schedules a
rangefinder dropout at a fixed vehicle time, so that test comes first (a test that finds its
moment passed fails and says so); the leg board is killed last.

"Safe" after an abort (docs/failsafes.md): not descending, the on-board reflex disarmed and the
script released (it reports IDLE), the autopilot holding in LOITER (or disarmed on the ground).
"""

from __future__ import annotations

import time

import pytest

from slopelander.controller.runner import Lander
from slopelander.controller.states.aborted import RISE_MAX_S
from slopelander_sitl.rig import Rig, config

#: its tests share a vehicle flown by several tests (rig): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("controller/flight_safety")

LOITER, GUIDED = 5, 4
#: above the roof: within the rangefinder's 3 m even at goto's 0.15 m tolerance, arriving from
#: above after an abort's 1 m rise (at 2.8 m it stopped at 2.91 m and the beam read 3 m: no range)
HOVER_M = 2.5
LOW_ARM = {"arm_height_m": 0.5}  # the descent lasts longer before the reflex is armed
DROPOUT_T = 45.0  # vehicle time (s) the rangefinder starts reporting NoData
DROPOUT_S = 3.0
SCENARIO = {
    # the pilot holds the throttle stick centred (LOITER holds height)
    "rc": [{"t": 0.0, "channels": {3: 1500}}],
    "faults": [{"kind": "rangefinder_dropout", "start": DROPOUT_T, "end": DROPOUT_T + DROPOUT_S}],
}


@pytest.fixture(scope="module")
def rig():
    with Rig(slope_deg=20.0, seed=3, scenario=SCENARIO) as r:
        r.take_off(3.0)
        yield r


def start_over_roof(rig: Rig, height_m: float = HOVER_M) -> None:
    """GUIDED (after an abort the vehicle is in LOITER) and hovering over the roof."""
    if rig.mode() != GUIDED:
        rig.wait_command(rig.link.command(176, 1, GUIDED), "GUIDED")  # MAV_CMD_DO_SET_MODE
        rig.fly_until(lambda: rig.mode() == GUIDED, 2.0, "report GUIDED")  # the next HEARTBEAT
    rig.go_over_roof(height_m)


def wait_until(rig: Rig, t: float) -> None:
    print(f"waiting from {rig.now:.1f} s to {t:g} s of vehicle time")
    if rig.now > t:
        pytest.fail(f"scheduled moment {t:g} s already passed (vehicle time {rig.now:.1f} s)")
    rig.wait(t - rig.now)


def assert_safe(rig: Rig, lander: Lander, why: str, clear_m: float = 0.5) -> None:
    """Two seconds after the autopilot took LOITER (an abort from the descent climbs 1 m first,
    states/aborted.py): ABORTED for ``why``, script IDLE, holding in LOITER."""
    t0 = rig.now
    while rig.mode() != LOITER and rig.now - t0 < RISE_MAX_S + 2.0:
        rig.wait(0.1, tick=lander.poll)
    rig.wait(2.0, tick=lander.poll)
    assert lander.machine.name == "ABORTED", lander.machine.history
    assert why in lander.machine.history[-1]["reason"], lander.machine.history[-1]
    assert rig.link.script_present and rig.link.script_state == 0  # reflex disarmed, released
    recent = [p for p in rig.track.pos if p[0] >= rig.now - 1.0]
    assert recent and min(p[4] for p in recent) > -0.1, recent[-3:]  # not descending (may climb back)
    assert rig.armed() and rig.mode() == LOITER, (rig.mode(), lander.act.pending, lander.machine.history[-2:])
    assert rig.height() > rig.surface_z(recent[-1][1]) + clear_m  # still clear of the roof


# --------------------------------------------------------------------------- failsafes
def test_a_rangefinder_dropout_during_the_descent_aborts_to_loiter(rig):
    start_over_roof(rig, HOVER_M)
    rig.set_legs(1.7, 2.3)
    wait_until(rig, DROPOUT_T - 2.0)
    lander = Lander(rig.link, config(reflex=LOW_ARM), (1.7, 2.3), legs=rig.legs)
    assert lander.run(30.0, until=("DESCEND", "ABORTED")) == "DESCEND"
    assert rig.now < DROPOUT_T  # descending when the rangefinder drops out
    assert lander.run(30.0, until=("ABORTED", "LANDED")) == "ABORTED", (lander.machine.history, rig.now)
    h = lander.machine.history
    assert [e["to"] for e in h][-2:] == ["DESCEND", "ABORTED"] and h[-1][
        "reason"
    ] == "range invalid or missing"
    # acted on while the range was missing (seen 0.02-0.4 s after it started; not yet explained
    # why not within one 50 Hz sample every time)
    assert DROPOUT_T <= h[-1]["t"] < DROPOUT_T + DROPOUT_S
    assert_safe(rig, lander, "range invalid")


# ------------------------------------------------------------------------------- aborts
@pytest.mark.parametrize(
    ("state", "preset"),
    [
        ("PRESET", (1.0, 1.0)),
        ("LEGS_WAIT", (1.7, 2.3)),
        ("CHECKS", (1.7, 2.3)),
        ("DESCEND", (1.7, 2.3)),
        ("ARMED", (1.7, 2.3)),
    ],
)
def test_an_abort_leaves_the_vehicle_safe(rig, state, preset):
    start_over_roof(rig)
    lander = Lander(rig.link, config(), preset, legs=rig.legs)
    if state in ("PRESET", "CHECKS"):  # states the machine passes within one step: enter directly
        if state == "CHECKS":
            rig.set_legs(*preset)
        lander.machine.transition(state, "test: landing requested", lander.inputs())
    else:
        assert lander.run(60.0, until=(state, "ABORTED")) == state, lander.machine.history
    if state == "ARMED":
        rig.wait(0.3, tick=lander.poll)
        assert rig.link.script_state == 10  # the reflex is armed on board
    lander.machine.transition("ABORTED", f"test: abort in {state}", lander.inputs())
    assert_safe(rig, lander, f"abort in {state}")


def test_a_leg_board_that_dies_during_the_descent_aborts_to_loiter(rig):
    start_over_roof(rig, HOVER_M)
    rig.set_legs(1.7, 2.3)
    lander = Lander(rig.link, config(), (1.7, 2.3), legs=rig.legs)
    assert lander.run(30.0, until=("DESCEND", "ABORTED")) == "DESCEND"
    rig.board.proc.kill()
    t0 = rig.now
    while lander.poll() != "ABORTED" and rig.now - t0 < 5.0:  # only the controller reads the legs now
        time.sleep(0.001)
    assert lander.machine.history[-1]["reason"].startswith("leg failure"), lander.machine.history[-1]
    rig.legs = None
    assert_safe(rig, lander, "leg failure")
