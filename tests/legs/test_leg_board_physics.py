"""The simulated board's physics and firmware, stepped in-process (no pty)."""

from __future__ import annotations

import math

import pytest

from sitl.legboard.physics import BoardParams, LegBoardPhysics
from slopelander.legs.messages import FaultCode, LegState

#: runs while the model compiles (tests/compile_once.py): nothing here needs it
pytestmark = pytest.mark.model_free

DT = 0.004


def run_until(board: LegBoardPhysics, done, limit_s: float) -> float:
    start = board.time_s
    while not done() and board.time_s - start < limit_s:
        board.step(DT)
    return board.time_s - start


def test_friction_torque_is_paper_equation_one():
    p = BoardParams()
    n, ro, ri = 18, 13e-3, 3.3e-3
    assert p.torque_per_newton == pytest.approx(2 * n / 3 * (ro**3 - ri**3) / (ro**2 - ri**2))
    # The paper's 75 N with μ ≈ 0.275 is about the 3.2 N·m the joint was sized for.
    assert p.torque_per_newton * 0.275 * 75 == pytest.approx(3.4, abs=0.1)


def test_loose_to_2_3_nm_takes_about_ten_seconds():
    board = LegBoardPhysics()
    p = board.params
    for leg in range(4):
        force = 2.3 / (p.torque_per_newton * p.mu[leg])
        board.set_friction(leg, round((p.i_no_load + p.amps_per_newton * force) * 1000))
    t = run_until(board, lambda: all(lg.state is LegState.HOLDING for lg in board.legs), 30)
    assert 8.0 <= t <= 12.0
    for leg in range(4):
        assert board.friction_torque_nm(leg) == pytest.approx(2.3, abs=0.05)


def test_held_leg_stays_where_landing_put_it_and_returns_when_loosened():
    board = LegBoardPhysics()
    board.set_friction(0, 100)
    run_until(board, lambda: board.legs[0].state is LegState.HOLDING, 30)
    board.set_joint_angle(0, 12.0)
    run_until(board, lambda: False, 2.0)
    assert board.legs[0].angle_deg == 12.0
    board.loosen(0)
    t = run_until(board, lambda: board.legs[0].state is LegState.LOOSE, 30)
    assert board.legs[0].angle_deg == pytest.approx(37.5)
    assert 3.0 < t < 15.0  # resetting a leg: about 10 s in the paper


def test_current_is_no_load_in_the_clearance_and_rises_with_clamping():
    board = LegBoardPhysics()
    board.set_friction(0, 150)
    run_until(board, lambda: False, 2.0)
    assert board.legs[0].current == pytest.approx(board.params.i_no_load)
    run_until(board, lambda: board.legs[0].state is LegState.HOLDING, 30)
    assert board.legs[0].current == pytest.approx(0.150, abs=0.002)


def test_reported_current_is_noisy_but_centred():
    board = LegBoardPhysics(seed=3)
    board.set_friction(1, 120)
    run_until(board, lambda: board.legs[1].state is LegState.HOLDING, 30)
    samples = [board.reports()[1].current_ma for _ in range(400)]
    mean = sum(samples) / len(samples)
    sd = math.sqrt(sum((s - mean) ** 2 for s in samples) / len(samples))
    true_ma = board.legs[1].current * 1000
    assert abs(true_ma - 120) <= board.params.band_ma  # inside the firmware's band
    assert mean == pytest.approx(true_ma, abs=0.5)
    assert 0.5 < sd < 3.0


@pytest.mark.parametrize(
    ("kind", "fault"), [("stuck", FaultCode.STUCK), ("overcurrent", FaultCode.OVERCURRENT)]
)
def test_injected_drive_faults_are_detected_by_the_firmware(kind, fault):
    board = LegBoardPhysics()
    board.inject(kind, 2)
    board.set_friction(2, 100)
    run_until(board, lambda: board.legs[2].state is LegState.FAULT, 5)
    assert board.legs[2].fault is fault


@pytest.mark.parametrize("kind", ["stuck", "overcurrent", "slip"])
def test_a_faulted_leg_is_loosened_once_the_fault_is_gone_and_then_takes_a_preset(kind):
    """The board answers a preset on a faulted leg "loosen it first"; loosening must work, also
    for a leg that faulted before its nut moved (it is at the back stop: reaching the stop at once
    is not a jam). It did not: the leg faulted "stuck" again, and every later landing was refused
    (found by the soak)."""
    board = LegBoardPhysics()
    board.inject(kind, 1)
    board.set_friction(1, 1500)
    run_until(board, lambda: board.legs[1].state is LegState.FAULT, 30)
    assert board.legs[1].state is LegState.FAULT
    board.clear_faults()  # the mechanic's fix
    board.loosen(1)
    run_until(board, lambda: board.legs[1].state is LegState.LOOSE, 10)
    assert board.legs[1].state is LegState.LOOSE and board.legs[1].fault is FaultCode.NONE
    assert board.set_friction(1, 1500) is None
    run_until(board, lambda: board.legs[1].state is LegState.HOLDING, 30)
    assert board.legs[1].state is LegState.HOLDING


def test_a_leg_still_jammed_faults_again_when_loosened():
    board = LegBoardPhysics()
    board.inject("stuck", 3)
    board.set_friction(3, 1500)
    run_until(board, lambda: board.legs[3].state is LegState.FAULT, 30)
    board.loosen(3)  # not cleared: the screw is still jammed
    run_until(board, lambda: board.legs[3].state is LegState.FAULT, 10)
    assert board.legs[3].state is LegState.FAULT and board.legs[3].fault is FaultCode.STUCK


def test_slipping_drive_times_out_on_the_board():
    board = LegBoardPhysics()
    board.inject("slip", 0)
    board.set_friction(0, 100)
    run_until(board, lambda: board.legs[0].state is LegState.FAULT, 40)
    assert board.legs[0].fault is FaultCode.TIMEOUT
    assert board.friction_torque_nm(0) == 0.0
