"""The controller's leg actions on the real simulated leg board (its own process, a real pty):
the uphill angle is set before the torques when the board can, and only reported when it cannot."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest

from slopelander.controller.actions import MavActions
from slopelander.controller.clock import ManualClock
from slopelander.controller.config import load_config
from slopelander.legs.calibration import load_calibration
from slopelander.legs.driver import LegBoard
from slopelander_sitl.legboard.runtime import silence_in_wall_time
from slopelander_sitl.vehicle.launch import REPO, child_env, start_legboard

HANG_S = 60.0  # only a bound against a hung test; the driver's timeouts run on the manual clock


@pytest.fixture
def board():
    lb = start_legboard(speed=20.0, config=silence_in_wall_time(20.0))
    legs = None
    try:
        legs = LegBoard.open(lb.pty, calibration=load_calibration(), clock=ManualClock())
        yield legs
    finally:
        if legs is not None:
            legs.close()
        lb.stop()


def drive(act: MavActions, legs: LegBoard) -> None:
    end = time.monotonic() + HANG_S
    while act.leg_op is None or not act.leg_op.done or act.legs_busy:
        legs.poll()
        act.advance()
        assert time.monotonic() < end, "the legs never finished"
        time.sleep(0.005)


def test_the_preset_sets_the_uphill_angle_then_the_torques(board):
    act = MavActions(None, load_config(), board)  # the leg actions never touch the MAVLink link
    assert act.can_set_angle()
    act.set_legs(1.1, 1.7, 25.7)
    assert act.leg_op.kind == "angle" and act.legs_busy
    drive(act, board)
    assert act.leg_op.kind == "friction" and act.leg_op.exception() is None
    angles = [s.angle_deg for s in board.status.legs]
    assert angles[0] == pytest.approx(25.7, abs=0.3) and angles[1] == pytest.approx(25.7, abs=0.3)
    assert angles[2:] == pytest.approx([37.5, 37.5], abs=0.3)
    tolerance = load_config()["legs.tolerance_nm"]
    for leg, r in act.leg_op.result().items():
        assert r.achieved == pytest.approx(1.1 if leg < 2 else 1.7, abs=tolerance)


def test_a_board_without_the_angle_stop_gets_only_the_torques(tmp_path):
    link = tmp_path / "legs"
    (tmp_path / "config.json").write_text(json.dumps(silence_in_wall_time(20.0)))
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "slopelander_sitl.legboard",
            "--link",
            str(link),
            "--speed",
            "20",
            "--config",
            str(tmp_path / "config.json"),
            "--no-angle-stop",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=child_env(),
        cwd=REPO,
    )
    try:
        assert proc.stdout.readline().startswith("legboard ready")
        with LegBoard.open(str(link), calibration=load_calibration(), clock=ManualClock()) as legs:
            act = MavActions(None, load_config(), legs)
            assert not act.can_set_angle()
            act.set_legs(1.1, 1.1, 25.7)
            assert act.leg_op.kind == "friction" and not act.legs_busy
            drive(act, legs)
            assert act.leg_op.exception() is None
            assert [s.angle_deg for s in legs.status.legs] == pytest.approx([37.5] * 4, abs=0.3)
    finally:
        proc.terminate()
        proc.wait(timeout=5)
        proc.stdout.close()


def test_the_lander_runs_the_legs_on_the_autopilots_clock(board):
    from slopelander.controller.link import Link
    from slopelander.controller.runner import Lander

    link = Link("udpin:127.0.0.1:0")  # nobody talks to it: vehicle time stands at 0
    try:
        cfg = load_config()
        Lander(link, cfg, (1.1, 1.1), legs=board)
        assert board.clock == link.clock.now and board.silence_timeout == cfg["legs.board_silent_s"]
        link.clock.observe_usec(7_000_000)
        assert board.clock() == 7.0
        op = board.start_loosen(timeout=2.0)
        assert op.deadline == 9.0  # the deadline is on vehicle time
    finally:
        link.close()
