"""Link cuts in landing states other than DESCEND, and leg faults injected in the real board
process during a flight, each checked against its row of docs/failsafes.md.

The companion's controller flies the simulated vehicle (real on-board script) and leg board as
processes in lock-step, its MAVLink link through the fault-injecting relay (slopelander_sitl.linkfault). One
vehicle on a 20 deg roof flies the module's tests in order. This is a fast representative subset;
``benchmarks/soak.py`` injects cuts of 0.5 s, 3 s and for good in every state, and every leg fault,
at random. Cuts last vehicle seconds: the relay paces the lock-stepped vehicle in real time while
the link is down (``slopelander_sitl.linkfault.Relay(lockstep=True)``).
"""

from __future__ import annotations

import contextlib
import time

import pytest

from slopelander.controller.runner import Lander
from slopelander_sitl.legboard.control import BoardControl
from slopelander_sitl.rig import Rig, RigError, config

#: its tests share a vehicle flown by several tests (rig): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("reliability/flight_faults")

LOITER, GUIDED = 5, 4
PRESET = (1.7, 2.3)
CUT = {"cut_height_m": 0.45}
# the pilot holds the throttle stick centred: LOITER holds its height after an abort
SCENARIO = {
    "rc": [{"t": 0.0, "channels": {3: 1500}}]
}  # 20 deg roof: the feet meet it near 0.3 m of range, ~1.2 m/s impact


@pytest.fixture(scope="module")
def rig():
    with Rig(slope_deg=20.0, seed=11, relay=True, scenario=SCENARIO) as r:
        r.take_off(3.0)
        yield r


class Told:
    """What the controller told the pilot (its STATUSTEXTs, still sent over the real link)."""

    def __init__(self, lander: Lander) -> None:
        self.texts: list[str] = []
        send = lander.link.send_statustext

        def record(text: str, *args) -> None:
            self.texts.append(text)
            send(text, *args)

        lander.link.send_statustext = record


def ready_over_roof(rig: Rig) -> None:
    rig.wait(0.5)  # an abort's mode change shows in the next heartbeats (5 Hz), not at once
    if not rig.armed():
        rig.take_off(3.0, force=True)
    if rig.mode() != GUIDED:
        rig.wait_command(rig.link.command(176, 1, GUIDED), "GUIDED")  # MAV_CMD_DO_SET_MODE
        rig.fly_until(lambda: rig.mode() == GUIDED, 2.0, "report GUIDED")
    rig.go_over_roof(2.0)


def run_until(rig: Rig, lander: Lander, states: tuple[str, ...], vehicle_s: float = 60.0) -> str:
    """Poll the landing until it has entered one of ``states`` (seen in its history)."""
    t0 = rig.now
    end = time.monotonic() + 120.0
    while rig.now - t0 < vehicle_s and time.monotonic() < end:
        lander.poll()
        rig.pilot_stick_down_while_disarmed()  # the scenario's pilot holds it centred otherwise
        for h in lander.machine.history:
            if h["to"] in states:
                return h["to"]
        time.sleep(0.001)
    pytest.fail(f"never reached {states}: {lander.machine.history}; script {rig.track.script[-8:]}")


def poll_for(lander: Lander, wall_s: float) -> None:
    """Keep the controller running for ``wall_s`` of wall time: while the link is cut the
    companion sees no vehicle time (the relay paces the vehicle in real time meanwhile)."""
    end = time.monotonic() + wall_s
    while time.monotonic() < end:
        lander.poll()
        time.sleep(0.002)


def link_back(rig: Rig, lander: Lander) -> None:
    rig.fly_until(lambda: lander.poll() == "ABORTED", 60.0, "see the link come back", wall_s=30.0)
    rig.wait(1.5, tick=lander.poll)


def assert_hovering_safe(rig: Rig) -> None:
    """Armed in LOITER, clear of the roof, the script released. The abort's mode command is sent
    again every ``link.command_timeout_s`` (0.5 s) of the companion's clock until acknowledged, 4 s
    of vehicle time at 8x: one run in a loaded suite (2026-11-27) read GUIDED 1.5 s of vehicle time
    after the abort (a first try lost at the cut's edge, suspected), so the mode is read once the
    retries have had their wall time."""
    with contextlib.suppress(RigError):
        rig.fly_until(lambda: rig.mode() == LOITER, 10.0, "switch to LOITER", wall_s=1.5)
    assert rig.armed() and rig.mode() == LOITER, (rig.armed(), rig.mode())
    x = rig.track.pos[-1][1]
    assert rig.height() - rig.surface_z(x) > 0.5, rig.track.pos[-1]
    assert rig.link.script_state == 0


# ----------------------------------------------------------------------------- link cuts
def test_a_3s_cut_in_takeoff_goes_link_lost_and_never_loosens_the_legs_low(rig):
    """TAKEOFF row: LINK_LOST; back: ABORTED (LOITER) once clear of the roof. Still below the clear
    height: armed, the take-off goes on (TAKEOFF again, to READY); disarmed, LANDED. Never armed
    in LOITER on the roof (seen before: it slid 20 m down it, docs/reliability.md). The legs keep
    their torque until the vehicle is clear."""
    ready_over_roof(rig)
    lander = Lander(rig.link, config(reflex=CUT), PRESET, legs=rig.legs)
    assert lander.run(60.0) == "LANDED", lander.machine.history[-3:]
    lander.takeoff_request = True
    run_until(rig, lander, ("TAKEOFF",))
    rig.relay.cut(3.0)
    poll_for(lander, 2.5)
    assert lander.machine.name == "LINK_LOST", lander.machine.history
    assert all(lg.state.name != "LOOSE" for lg in rig.legs.status.legs), rig.legs.status
    rig.fly_until(lambda: lander.poll() != "LINK_LOST", 60.0, "see the link come back", wall_s=30.0)
    hist = lander.machine.history
    i = max(k for k, h in enumerate(hist) if h["to"] == "LINK_LOST")
    assert hist[i]["from"] == "TAKEOFF" and i + 1 < len(hist), hist[i - 1 :]
    back = hist[i + 1]
    if back["to"] == "ABORTED":  # the take-off got through: clear of the roof, LOITER holds it
        rig.wait(1.5, tick=lander.poll)
        assert_hovering_safe(rig)
        return
    # still near the roof. Armed: the take-off asked for goes on. Disarmed (the arm never came):
    # LANDED, and the pilot's take-off request, still standing, starts it again from there
    assert back["to"] in ("TAKEOFF", "LANDED"), back
    reason = "taking off again" if back["to"] == "TAKEOFF" else "disarmed on the roof"
    assert reason in back["reason"], back
    assert run_until(rig, lander, ("READY", "ABORTED")) == "READY", lander.machine.history[i:]
    x = rig.track.pos[-1][1]
    assert rig.armed() and rig.height() - rig.surface_z(x) > 0.5, (rig.track.pos[-1], hist[i:])


@pytest.mark.parametrize("state", ["REVERSE"])
def test_a_half_second_cut_is_ridden_out_and_the_landing_goes_on(rig, state):
    """A cut shorter than ``link.link_loss_s`` is not a lost link: the landing goes on and ends
    LANDED (in DESCEND: on both autopilots, tests/flights/test_landings_on_both_autopilots.py).
    The cut lasts 0.5 s of vehicle time (the relay paces the vehicle in real time during
    it); the companion judges loss on its own clock, so if the machine stretched the silence past
    the loss time the LINK_LOST row must apply instead (checked too, and said)."""
    ready_over_roof(rig)
    lander = Lander(rig.link, config(reflex=CUT), PRESET, legs=rig.legs)
    run_until(rig, lander, (state,))
    silent_wall = rig.cut_link(0.5, lander.poll)
    end = lander.run(60.0)
    states = [h["to"] for h in lander.machine.history]
    loss_s = lander.cfg["link.link_loss_s"]
    if silent_wall < loss_s - 0.2:
        assert "LINK_LOST" not in states and end == "LANDED", lander.machine.history
    else:  # the loaded machine made the silence long enough to be a lost link
        assert "LINK_LOST" in states, (silent_wall, lander.machine.history)
        assert end == ("LANDED" if state == "REVERSE" else "ABORTED"), lander.machine.history
    if end == "LANDED":  # disarmed deliberately (the heartbeats tell within a few tenths)
        rig.fly_until(lambda: lander.poll() and not rig.armed(), 2.0, "report the disarm")


def test_a_3s_cut_in_legs_wait_aborts_to_loiter_when_the_link_is_back(rig):
    ready_over_roof(rig)
    # a fresh driver: the last one measured its timeouts on the autopilot's clock, which jumped
    # over the previous cut while only the controller (which tells it so) was watching. The new
    # one is on the vehicle's clock too: on the wall clock a loaded machine reads as a silent board
    op = rig.open_legs().start_loosen()
    rig.fly_until(lambda: op.done, 30.0, "loosen the legs")
    lander = Lander(rig.link, config(reflex=CUT), PRESET, legs=rig.legs)
    run_until(rig, lander, ("LEGS_WAIT",))
    rig.relay.cut(3.0)
    poll_for(lander, 2.5)
    assert lander.machine.name == "LINK_LOST", lander.machine.history
    link_back(rig, lander)
    assert [h["to"] for h in lander.machine.history][-2:] == ["LINK_LOST", "ABORTED"]
    assert_hovering_safe(rig)


def test_a_3s_cut_after_the_cut_ends_disarmed_on_the_roof_legs_clamped(rig):
    """CUT/REVERSE/SETTLED row: LINK_LOST while the script goes on with its bounded sequence; when
    the link is back (3 s of vehicle time later, the reverse thrust still on or ramping) the
    landing is judged as it lies: SETTLED, disarmed at rest, LANDED. Nothing is released."""
    ready_over_roof(rig)
    lander = Lander(rig.link, config(reflex=CUT), PRESET, legs=rig.legs)
    run_until(rig, lander, ("CUT", "REVERSE", "SETTLED"))  # one row of the table: the first seen
    rig.relay.cut(3.0)
    poll_for(lander, 2.5)
    assert lander.machine.name == "LINK_LOST", lander.machine.history
    rig.fly_until(lambda: lander.poll() in ("LANDED", "ABORTED"), 30.0, "end the landing", wall_s=60.0)
    states = [h["to"] for h in lander.machine.history]
    assert states[-1] == "LANDED" and "ABORTED" not in states, lander.machine.history
    rig.wait(1.0, tick=lander.poll)
    assert not rig.armed()
    x = rig.track.pos[-1][1]
    assert rig.height() - rig.surface_z(x) < 0.4  # on the roof
    assert all(lg.torque_nm > 1.0 for lg in rig.legs.status.legs), rig.legs.status  # still clamped


# ------------------------------------------------------------------------------ leg faults
@pytest.mark.parametrize(
    ("kind", "state", "why"),
    [
        ("overcurrent", "LEGS_WAIT", "leg failure"),  # one leg does not reach its torque
        ("stuck", "LEGS_WAIT", "leg failure"),  # a motor stalls
        ("corrupt", "LEGS_WAIT", "leg failure"),  # every byte from the board garbled
        pytest.param("unplug", "DESCEND", "leg failure"),  # the port disappears
    ],
)
def test_a_leg_fault_aborts_before_the_motors_stop_and_the_pilot_is_told(kind, state, why):
    """A vehicle of its own each: a leg that faulted stays faulted (the board needs service)."""
    with Rig(slope_deg=20.0, seed=12, relay=False, scenario=SCENARIO) as rig:
        rig.take_off(3.0)
        rig.go_over_roof(2.0)
        lander = Lander(rig.link, config(reflex=CUT), PRESET, legs=rig.legs)
        told = Told(lander)
        run_until(rig, lander, (state,))
        with BoardControl(rig.board.control) as ctl:
            if kind in ("overcurrent", "stuck"):
                ctl.inject(kind, leg=1)
            elif kind == "corrupt":
                ctl.inject(kind, rate=1.0)
            else:
                ctl.inject(kind)
        t0 = rig.now
        assert lander.run(40.0, until=("ABORTED", "LANDED")) == "ABORTED", lander.machine.history
        h = lander.machine.history[-1]
        assert h["reason"].startswith(why) and h["from"] in ("LEGS_WAIT", "CHECKS", "DESCEND", "ARMED"), h
        assert not rig.track.event_times("EV_STOP", t0)  # aborted before the motors stop
        assert any(t.startswith("SL ABORTED: leg failure") for t in told.texts), told.texts
        rig.wait(2.0, tick=lander.poll)
        assert_hovering_safe(rig)
        if kind == "unplug":
            rig.legs = None  # the port is gone
