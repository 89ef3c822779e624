"""How a landing ends, in the real script (real Lua 5.3): from the cut on the motors stay held
until a disarm (the companion's request, or its silence, only with the vehicle still), a take-off
release with the vehicle level enough, or the pilot's emergency stop (issue 20 item 4, issue 21)."""

from __future__ import annotations

import math

import pytest
from script_bench import Bench
from test_script_reflex import CUT_M, IMPACT, PCT, SAMPLE_MS, cut_now, good, impact

from slopelander.controller.script_contract import CMD_ACTUATOR, CMD_REFLEX, STILL_S, Reflex, ScriptState

ACCEPTED, TEMP_REJECTED = 0, 1
STILL_MS = round(STILL_S * 1000)


def held(bench: Bench, validity_ms: float = 3000) -> None:
    """Landed: the descent (0.5 m/s down), cut, impact (then still), reverse thrust (300 ms, no
    ramp), then HOLD: still for about 320 ms."""
    bench.io.velocity = (0.0, 0.0, 0.5)
    cut_now(bench, validity_ms=validity_ms)
    impact(bench)
    bench.io.velocity = (0.0, 0.0, 0.0)
    bench.run(320)
    assert bench.io.state() == ScriptState.HOLD and bench.outputs() == [1500] * 4


def test_disarm_request_disarms_a_held_vehicle_once_still_for_a_second(bench: Bench) -> None:
    """Issue 40 finding 7: still for 0.3 s is not enough; still for STILL_S (1 s, ArduCopter's own
    land detector's time) is."""
    held(bench)
    ack = bench.command(CMD_REFLEX, Reflex.DISARM)
    assert ack.result == TEMP_REJECTED and bench.io.sl_texts()[-1] == "SL: disarm: still for 0.3 s of 1.0"
    assert bench.io.armed and bench.io.state() == ScriptState.HOLD
    bench.run(STILL_MS - 340)
    ack = bench.command(CMD_REFLEX, Reflex.DISARM)
    assert ack.result == ACCEPTED
    assert not bench.io.armed and bench.io.state() == ScriptState.IDLE
    assert bench.command(CMD_REFLEX, Reflex.DISARM).result == ACCEPTED  # already disarmed


def stick_slip(bench: Bench, sticks: int = 10, slide_ms: int = 170, stick_ms: int = 30):
    """A vehicle sliding down the roof at 0.3 m/s whose feet stick for ``stick_ms`` every
    ``slide_ms``: the speed reads 0 for the stick, the body rates stay small. Returns a
    function that runs one slide and one stick, with ``during_stick()`` called in each stick."""

    def cycle(during_stick=None) -> None:
        bench.io.velocity = (0.25, 0.0, 0.17)
        bench.run(slide_ms)
        bench.io.velocity = (0.0, 0.0, 0.0)
        bench.run(stick_ms // 2)
        if during_stick is not None:
            during_stick()
        bench.run(stick_ms - stick_ms // 2)

    return cycle


def test_a_vehicle_whose_feet_stick_for_an_instant_is_not_disarmed(bench: Bench) -> None:
    """Issue 40 finding 7: a disarm judged on one sample passes a sliding vehicle whose feet stick
    for an instant (or one at the top of a bounce). Asked during each stick, the script refuses;
    a silent companion's HOLD does not disarm it either; the motors stay held stopped."""
    held(bench, validity_ms=500)  # the companion goes silent: its validity lapses in the slide
    cycle = stick_slip(bench)
    answers = []

    def ask() -> None:
        ack = bench.command(CMD_REFLEX, Reflex.DISARM, wait_ms=2)
        answers.append((ack.result, bench.io.sl_texts()[-1]))

    for _ in range(10):
        cycle(ask)
    assert all(r == TEMP_REJECTED for r, _ in answers), answers
    assert all(t.startswith("SL: disarm: still for 0.0 s") for _, t in answers), answers
    assert bench.io.armed and bench.io.state() == ScriptState.HOLD and bench.outputs() == [1500] * 4
    bench.run(STILL_MS + 20)  # it stops for good: disarmed by the silent companion's rule
    assert not bench.io.armed and "SL: companion silent after landing: disarmed" in bench.io.sl_texts()


def test_the_top_of_a_bounce_is_not_still(bench: Bench) -> None:
    """A vehicle bouncing on the roof (0.6 m/s up, 120 ms in the air): at the top of each bounce its
    vertical speed passes through zero and the body rates are small; asked there, the script refuses."""
    held(bench)
    results = []

    def flight(t0: int):
        return lambda t: setattr(bench.io, "velocity", (0.0, 0.0, -0.6 + 9.81 * (t - t0) / 1000))

    for _ in range(8):
        t0 = bench.io.now_ms
        bench.run(61, flight(t0))
        assert abs(bench.io.velocity[2]) < 0.02  # the top
        ack = bench.command(CMD_REFLEX, Reflex.DISARM, wait_ms=3)
        results.append((ack.result, bench.io.sl_texts()[-1]))
        bench.run(59, flight(t0))
    assert all(r == TEMP_REJECTED and "still for 0.0 s" in why for r, why in results), results
    assert bench.io.armed and bench.io.state() == ScriptState.HOLD


@pytest.mark.parametrize(
    ("change", "why"),
    [
        ({"gyro_rads": (0.0, math.radians(8), 0.0)}, "SL: disarm: turning 8 deg/s"),
        ({"velocity": (0.15, 0.0, 0.05)}, "SL: disarm: moving 0.16 m/s"),
        ({"velocity": None}, "SL: disarm: velocity unknown"),
    ],
)
def test_disarm_request_refused_while_moving(bench: Bench, change: dict, why: str) -> None:
    """A slide or a pivot is not disarmed: the motors stay held and the companion is told why."""
    held(bench)
    for k, v in change.items():
        setattr(bench.io, k, v)
    ack = bench.command(CMD_REFLEX, Reflex.DISARM)
    assert ack.result == TEMP_REJECTED and bench.io.sl_texts()[-1] == why
    assert bench.io.armed and bench.io.state() == ScriptState.HOLD and bench.outputs() == [1500] * 4


def test_disarm_request_refused_without_the_motors_held(bench: Bench) -> None:
    bench.io.range = good(1.0)
    assert bench.command(CMD_REFLEX, Reflex.SETUP, 0, 0.5).result == ACCEPTED
    assert bench.command(CMD_REFLEX, Reflex.ARM, CUT_M, IMPACT, PCT, 300, 3000).result == ACCEPTED
    ack = bench.command(CMD_REFLEX, Reflex.DISARM)  # in the air, reflex armed
    assert ack.result == TEMP_REJECTED and bench.io.sl_texts()[-1] == "SL: disarm: motors not held stopped"
    assert bench.io.armed


def test_a_silent_companion_disarms_only_a_still_vehicle(bench: Bench) -> None:
    """Validity lapsed in HOLD: a vehicle still moving stays armed with its motors held (never
    released), and is disarmed once it is still."""
    held(bench, validity_ms=1000)
    bench.io.velocity = (0.3, 0.0, 0.1)  # sliding
    bench.run(1500)
    assert bench.io.armed and bench.io.state() == ScriptState.HOLD and bench.outputs() == [1500] * 4
    assert "SL: companion silent, moving 0.32 m/s: holding" in bench.io.sl_texts()
    bench.io.velocity = (0.0, 0.0, 0.0)
    bench.run(STILL_MS - 20)
    assert bench.io.armed  # still, but not yet for STILL_S
    bench.run(40)
    assert not bench.io.armed and bench.io.state() == ScriptState.IDLE
    assert "SL: companion silent after landing: disarmed" in bench.io.sl_texts()


@pytest.mark.parametrize("cmd", [(CMD_REFLEX, Reflex.ABORT), (CMD_ACTUATOR, 0), (CMD_ACTUATOR, 1, 0, 100)])
def test_nothing_but_disarm_take_off_or_estop_releases_a_held_vehicle(bench: Bench, cmd) -> None:
    """An abort, a release, or a commanded stop (whose own validity would lapse to the mixer)."""
    held(bench)
    assert bench.command(*cmd).result == TEMP_REJECTED
    bench.run(500)
    assert bench.io.state() == ScriptState.HOLD and bench.outputs() == [1500] * 4


def test_take_off_release_only_level_enough(bench: Bench) -> None:
    held(bench)
    bench.io.attitude_rad = (0.0, math.radians(35), 0.0)  # on a 35 deg roof
    ack = bench.command(CMD_REFLEX, Reflex.TAKEOFF_RELEASE, 25)
    assert ack.result == TEMP_REJECTED and bench.io.sl_texts()[-1] == "SL: take-off release: tilted 35 deg"
    assert bench.io.state() == ScriptState.HOLD
    bench.io.attitude_rad = (math.radians(10), math.radians(15), 0.0)  # 18 deg from level
    assert bench.command(CMD_REFLEX, Reflex.TAKEOFF_RELEASE, 25).result == ACCEPTED
    bench.run(40)
    assert bench.io.state() == ScriptState.IDLE and bench.outputs() == [None] * 4 and bench.io.armed


def stall(bench: Bench, ms: int) -> None:
    """The vehicle's clock runs on while the scripting thread is not scheduled (a loaded host)."""
    bench.io.now_ms += ms


def test_a_stalled_script_keeps_the_held_motors_stopped(bench: Bench) -> None:
    """ArduPilot counts an override's timeout in main-loop ticks: a held vehicle on the roof must
    not get its (armed) mixer back because the script was not run for a while."""
    held(bench)
    stall(bench, 200)
    assert bench.outputs() == [1500] * 4
    bench.run(1)
    assert bench.io.state() == ScriptState.HOLD and bench.outputs() == [1500] * 4


def test_a_stalled_script_keeps_the_motors_cut_in_the_fall(bench: Bench) -> None:
    """Issue 40 finding 9: CUT's override lasted 30 ms, so a scripting thread not scheduled for
    longer (40 ms stalls were seen on ArduCopter SITL) handed the falling vehicle back to a mixer
    demanding climb. From the cut on the motors hold through a stall of up to 250 ms."""
    cut_now(bench)
    assert bench.io.state() == ScriptState.CUT
    for gap in (40, 100, 240):
        stall(bench, gap)
        assert bench.outputs() == [1500] * 4, gap
        bench.run(2)
    assert bench.io.state() in (ScriptState.CUT, ScriptState.HOLD)


def test_a_false_cut_gives_the_motors_back_at_once(bench: Bench) -> None:
    """The long hold never outlives CUT: a false cut (the range above the cut height at the
    bound) clears it at once, and the autopilot flies the vehicle."""
    cut_now(bench)
    bench.io.range = good(0.8)
    bench.io.accel_body = (0.0, 0.0, -0.3)  # falling freely: nothing under it
    for _ in range(600):
        bench.run(1)
        if bench.io.state() == ScriptState.IDLE:
            break
    assert bench.io.state() == ScriptState.IDLE and bench.outputs() == [None] * 4


def test_a_stalled_script_keeps_the_reverse_thrust(bench: Bench) -> None:
    cut_now(bench)
    impact(bench)
    assert bench.io.state() == ScriptState.RVT
    stall(bench, 100)
    assert bench.outputs() == [1500 - 5 * int(PCT)] * 4


def test_a_disarm_gives_the_outputs_back_at_once(bench: Bench) -> None:
    """The long hold is cleared when the landing ends, not left to lapse."""
    held(bench)
    bench.run(STILL_MS)
    assert bench.command(CMD_REFLEX, Reflex.DISARM, wait_ms=2).result == ACCEPTED
    assert not bench.io.armed and bench.outputs() == [None] * 4


def test_take_off_release_refused_during_the_reverse_thrust(bench: Bench) -> None:
    cut_now(bench)
    impact(bench)
    assert bench.command(CMD_REFLEX, Reflex.TAKEOFF_RELEASE, 25).result == TEMP_REJECTED
    assert bench.io.state() == ScriptState.RVT


def test_emergency_stop_releases_a_held_vehicle(bench: Bench) -> None:
    held(bench)
    bench.io.estop = True
    bench.run(40)
    assert bench.io.state() == ScriptState.ESTOP and bench.outputs() == [None] * 4


def test_arm_needs_the_landings_setup(bench: Bench) -> None:
    """The missed-impact bound needs the descent rate: no ARM before a SETUP."""
    bench.io.range = good(1.0)
    bench.run(SAMPLE_MS)
    ack = bench.command(CMD_REFLEX, Reflex.ARM, CUT_M, IMPACT, PCT, 300, 3000)
    assert ack.result == TEMP_REJECTED and bench.io.sl_texts()[-1] == "SL: reflex not set up"
    assert bench.io.state() == ScriptState.IDLE
