"""The leg-board firmware over its plant model, in this process (no pty): the clamp, the
loosening, the protections, the power-up probe and the companion-silence rule.

The same source runs on MicroPython (``test_micropython_firmware.py``); here it runs on CPython,
where a failure is easiest to read.
"""

from __future__ import annotations

import math

import pytest

from slopelander.legs import wire
from slopelander.legs.messages import FaultCode, LegState
from slopelander_sitl.legboard.runtime import HostBoard

STEP_S = 0.02


def run_until(board: HostBoard, done, limit_s: float) -> float:
    """Board seconds until ``done()`` (or ``limit_s``)."""
    start = board.time_s
    while not done() and board.time_s - start < limit_s:
        board.advance(board.time_s + STEP_S)
    return board.time_s - start


def target_ma(board: HostBoard, leg: int, torque_nm: float) -> int:
    """The current at which this plant's leg holds ``torque_nm`` (its own, true curve)."""
    p = board.plant.p
    force = torque_nm / (p.torque_per_newton() * p.mu[leg])
    return round((p.i_no_load + p.amps_per_newton() * force) * 1000)


def state(board: HostBoard, leg: int) -> LegState:
    return LegState(board.fw.legs[leg].state)


def fault(board: HostBoard, leg: int) -> FaultCode:
    return FaultCode(board.fw.legs[leg].fault)


def test_friction_torque_is_paper_equation_one():
    p = HostBoard().plant.p
    n, ro, ri = 18, 13e-3, 3.3e-3
    assert p.torque_per_newton() == pytest.approx(2 * n / 3 * (ro**3 - ri**3) / (ro**2 - ri**2))
    # The paper's 75 N with μ ≈ 0.275 is about the 3.2 N·m the joint was sized for.
    assert p.torque_per_newton() * 0.275 * 75 == pytest.approx(3.4, abs=0.1)


def test_the_board_powers_up_with_its_legs_found_loose():
    board = HostBoard()
    assert [state(board, i) for i in range(4)] == [LegState.LOOSE] * 4
    assert all(leg.known for leg in board.fw.legs)  # the back stop is the encoder's zero
    assert board.time_s < 0.1


def test_loose_to_the_paper_levels_in_about_ten_seconds_and_on_the_torque():
    board = HostBoard()
    levels = (0.56, 1.1, 1.7, 2.3)
    for leg, tau in enumerate(levels):
        board.fw.legs[leg].set_friction(target_ma(board, leg, tau))
    t = run_until(board, lambda: state(board, 3) is LegState.HOLDING, 30)
    assert 8.0 <= t <= 12.0  # loose → 2.3 N·m: the paper's ≈10 s
    run_until(board, lambda: all(state(board, i) is LegState.HOLDING for i in range(4)), 5)
    for leg, tau in enumerate(levels):
        # the clamp ends within about a milliampere of its target (docs/leg-protocol.md §6)
        assert board.plant.legs[leg].friction_torque() == pytest.approx(tau, abs=0.08)


def test_held_leg_stays_where_the_landing_put_it_and_returns_when_loosened():
    board = HostBoard()
    board.fw.legs[0].set_friction(100)
    run_until(board, lambda: state(board, 0) is LegState.HOLDING, 30)
    board.control({"op": "set_angles", "deg": [12.0, None, None, None]})
    run_until(board, lambda: False, 2.0)
    assert board.plant.legs[0].angle_deg == 12.0
    board.fw.legs[0].loosen()
    t = run_until(board, lambda: state(board, 0) is LegState.LOOSE, 30)
    run_until(board, lambda: False, 1.0)
    assert board.plant.legs[0].angle_deg == pytest.approx(37.5)
    assert 3.0 < t < 15.0  # resetting a leg: about 10 s in the paper


def test_current_is_no_load_in_the_clearance_and_the_target_when_held():
    board = HostBoard()
    board.fw.legs[0].set_friction(150)
    run_until(board, lambda: False, 2.0)
    assert board.plant.legs[0].current == pytest.approx(board.plant.p.i_no_load, abs=0.001)
    run_until(board, lambda: state(board, 0) is LegState.HOLDING, 30)
    assert board.plant.legs[0].current == pytest.approx(0.150, abs=0.002)
    reports = []
    for _ in range(50):
        board.advance(board.time_s + 0.1)
        reports.append(board.fw.legs[0].report()[2])
    assert abs(sum(reports) / len(reports) - 150) <= 1.0  # the reported current is centred


@pytest.mark.parametrize(
    ("kind", "code"),
    [
        ("stuck", FaultCode.STUCK),
        ("overcurrent", FaultCode.OVERCURRENT),
        ("sense", FaultCode.SENSE),
        ("slip", FaultCode.TRAVEL),
    ],
)
def test_injected_drive_faults_are_detected_by_the_firmware(kind, code):
    board = HostBoard()
    board.inject(kind, 2)
    board.fw.legs[2].set_friction(100)
    t = run_until(board, lambda: state(board, 2) is LegState.FAULT, 30)
    assert fault(board, 2) is code
    if kind != "slip":  # found within a fraction of a second, before the nut moved far
        assert t < 0.5 and board.plant.legs[2].travel < 0.2e-3
    else:  # the motor turns, the nut does not: found when the encoder passes the nut's range
        assert 10.0 < t < 16.0
    assert board.plant.legs[2].volts == 0.0  # the motor is off (braked)


def test_a_sense_that_dies_while_holding_is_a_fault_before_the_clamp_grows():
    board = HostBoard()
    board.fw.legs[1].set_friction(100)
    run_until(board, lambda: state(board, 1) is LegState.HOLDING, 30)
    before = board.plant.legs[1].friction_torque()
    board.inject("sense", 1)
    t = run_until(board, lambda: state(board, 1) is LegState.FAULT, 5)
    assert fault(board, 1) is FaultCode.SENSE and t < 1.0
    assert board.plant.legs[1].friction_torque() < before + 0.1


@pytest.mark.parametrize("kind", ["stuck", "overcurrent", "slip", "sense"])
def test_a_faulted_leg_is_loosened_once_the_fault_is_gone_and_then_takes_a_preset(kind):
    board = HostBoard()
    board.inject(kind, 1)
    board.fw.legs[1].set_friction(150)
    run_until(board, lambda: state(board, 1) is LegState.FAULT, 30)
    assert state(board, 1) is LegState.FAULT
    assert board.fw.legs[1].set_friction(150) == wire.NAK_FAULTED
    board.clear_faults()  # the mechanic's fix
    board.fw.legs[1].loosen()
    run_until(board, lambda: state(board, 1) is LegState.LOOSE, 20)
    assert state(board, 1) is LegState.LOOSE and fault(board, 1) is FaultCode.NONE
    assert board.fw.legs[1].set_friction(150) is None
    run_until(board, lambda: state(board, 1) is LegState.HOLDING, 30)
    assert state(board, 1) is LegState.HOLDING


def test_a_leg_still_jammed_faults_again_at_the_next_clamp():
    board = HostBoard()
    board.inject("stuck", 3)
    board.fw.legs[3].set_friction(150)
    run_until(board, lambda: state(board, 3) is LegState.FAULT, 30)
    board.fw.legs[3].loosen()  # not cleared: the screw is still jammed, at its back stop
    run_until(board, lambda: state(board, 3) is not LegState.LOOSENING, 10)
    board.fw.legs[3].set_friction(150)
    run_until(board, lambda: state(board, 3) is LegState.FAULT, 5)
    assert fault(board, 3) is FaultCode.STUCK


def test_a_jam_midway_back_is_stuck_not_the_back_stop():
    """The encoder says where the nut is: a stall 4 mm from the stop is not the stop."""
    board = HostBoard()
    board.fw.legs[0].set_friction(120)
    run_until(board, lambda: state(board, 0) is LegState.HOLDING, 30)
    board.inject("stuck", 0)
    board.fw.legs[0].loosen()
    run_until(board, lambda: state(board, 0) is not LegState.LOOSENING, 5)
    assert fault(board, 0) is FaultCode.STUCK


def test_a_leg_clamped_at_power_up_is_stopped_and_loosened_before_a_clamp():
    """The firmware cannot know an old clamp: its probe finds the nut away from the stop, says
    STOPPED, and the next clamp backs it off first (a lower target on a self-locking screw)."""
    board = HostBoard(plant={"start_travel": 4.0e-3})
    assert [state(board, i) for i in range(4)] == [LegState.STOPPED] * 4
    clamp = board.plant.legs[0].friction_torque()
    assert clamp > 1.0  # the probe's gentle pull left the clamp on
    board.fw.legs[0].set_friction(70)
    assert state(board, 0) is LegState.LOOSENING
    run_until(board, lambda: state(board, 0) is LegState.HOLDING, 40)
    assert board.plant.legs[0].friction_torque() == pytest.approx(
        board.plant.p.torque_at_current(0, 0.070), abs=0.08
    )


def test_a_dead_current_sense_is_found_at_power_up():
    from legfw.plant import Plant

    class DeadSense(HostBoard):
        pass

    board = HostBoard.__new__(DeadSense)
    # the plant with leg 2's sense dead before the firmware first runs
    original = Plant.__init__

    def dead(self, *a, **kw):
        original(self, *a, **kw)
        self.legs[2].sense_dead = True

    Plant.__init__ = dead
    try:
        HostBoard.__init__(board)
    finally:
        Plant.__init__ = original
    assert state(board, 2) is LegState.FAULT and fault(board, 2) is FaultCode.SENSE
    assert state(board, 1) is LegState.LOOSE


def test_a_silent_companion_leaves_the_clamps_but_switches_the_motors_off():
    board = HostBoard()
    board.fw.handle(wire.HELLO, 0, (wire.PROTOCOL_VERSION, 100))
    board.fw.handle(wire.SET_FRICTION, 1, (0b0011, (100, 105, 0, 0)))  # held in about 9 s
    run_until(board, lambda: state(board, 1) is LegState.HOLDING, 30)
    torques = [board.plant.legs[i].friction_torque() for i in (0, 1)]
    heard = board.fw.last_heard_ms / 1000.0
    assert state(board, 0) is LegState.HOLDING
    run_until(board, lambda: state(board, 0) is LegState.STOPPED, 15)
    silent_s = board.time_s - heard
    assert 10.0 <= silent_s <= 10.1  # board.cfg.silence_ms
    assert [state(board, i) for i in range(4)] == [LegState.STOPPED] * 2 + [LegState.LOOSE] * 2
    assert [board.plant.legs[i].volts for i in (0, 1)] == [0.0, 0.0]
    stopped = [board.plant.legs[i].friction_torque() for i in (0, 1)]
    assert stopped == pytest.approx(torques, abs=0.02)  # the clamps as they were held
    run_until(board, lambda: False, 5.0)
    later = [board.plant.legs[i].friction_torque() for i in (0, 1)]
    assert later == pytest.approx(stopped, abs=1e-4)  # the screws hold them (the braked rotor's last turn)
    run_until(board, lambda: False, 5.0)
    assert [board.plant.legs[i].friction_torque() for i in (0, 1)] == later  # and nothing moves
    # the companion back: the same target takes the hold up again, without moving the nut
    board.fw.handle(wire.SET_FRICTION, 2, (0b0001, (100, 0, 0, 0)))
    run_until(board, lambda: state(board, 0) is LegState.HOLDING, 2)
    assert board.plant.legs[0].friction_torque() == pytest.approx(torques[0], abs=0.02)


def test_a_keepalive_is_enough_to_keep_the_motors_held():
    board = HostBoard()
    board.fw.handle(wire.HELLO, 0, (wire.PROTOCOL_VERSION, 100))
    board.fw.handle(wire.SET_FRICTION, 1, (0b0001, (100, 0, 0, 0)))
    for _ in range(300):  # 30 s
        board.advance(board.time_s + 0.1)
        board.fw.handle(wire.KEEPALIVE, 2, ())
    assert state(board, 0) is LegState.HOLDING


def test_a_target_above_the_boards_limit_is_refused_whole():
    board = HostBoard()
    board.fw.handle(wire.HELLO, 0, (wire.PROTOCOL_VERSION, 100))
    assert board.fw.apply(wire.SET_FRICTION, (0b0011, (100, 176, 0, 0))) == wire.NAK_ABOVE_LIMIT
    assert [state(board, i) for i in (0, 1)] == [LegState.LOOSE, LegState.LOOSE]


def test_the_rest_stop_sets_the_angle_and_the_leg_returns_to_it():
    board = HostBoard(config={"angle_stop": True})
    board.fw.legs[0].set_angle(2400)
    t = run_until(board, lambda: state(board, 0) is LegState.LOOSE, 10)
    assert board.plant.legs[0].angle_deg == pytest.approx(24.0, abs=0.2)
    assert t == pytest.approx((37.5 - 24.0) / 15.0, abs=0.3)  # 15 deg/s
    board.fw.legs[0].set_friction(80)
    run_until(board, lambda: state(board, 0) is LegState.HOLDING, 30)
    board.control({"op": "set_angles", "deg": [12.0, None, None, None]})
    board.fw.legs[0].loosen()
    run_until(board, lambda: state(board, 0) is LegState.LOOSE, 30)
    run_until(board, lambda: False, 1.0)
    assert board.plant.legs[0].angle_deg == pytest.approx(24.0, abs=0.2)


def test_host_and_wire_time_stay_whole_ticks():
    board = HostBoard()
    t0 = board.time_s
    board.advance(t0 + 1.0)
    assert math.isclose((board.time_s - t0) * 1000 % 4, 0, abs_tol=1e-6)
