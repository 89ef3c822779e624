"""The vehicle and the simulated leg board as two processes: torques set over the serial link
with the LegBoard driver reach the vehicle's physics, and the vehicle's joint angles reach the
board while it stands on the pad."""

from __future__ import annotations

import time
from pathlib import Path

from slopelander.legs import LegBoard
from slopelander_sitl.legboard.control import BoardControl
from slopelander_sitl.vehicle.launch import start_legboard, start_vehicle
from tests.legs.fed_clock import board_time, feed_until_done
from tests.vehicle.conftest import ROUTE_A


def _angles(ctl: BoardControl) -> list[float]:
    return [float(leg["angle_deg"]) for leg in ctl.state()["legs"]]


def _stand(control: Path, ctl: BoardControl) -> list[float]:
    """The board's angles after a vehicle stood 1.5 s on the pad with its legs: the board's time
    is ahead of the vehicle's, so it holds still and keeps the angles the vehicle wrote."""
    v = start_vehicle(params=ROUTE_A, no_script=True, legboard_control=control)
    try:
        time.sleep(1.5)
        return _angles(ctl)
    finally:
        assert v.stop() == 0


def test_torques_in_angles_out():
    lb = start_legboard(clock="external")  # fed by this test, then held still by the vehicles
    try:
        with BoardControl(lb.control) as ctl:
            board = LegBoard.open(lb.pty)
            board_time(board, ctl)
            try:
                t = feed_until_done(board, ctl, board.start_torques({leg: 2.3 for leg in range(4)}), 30.0)
                held = _angles(ctl)
                clamped = _stand(lb.control, ctl)
                feed_until_done(board, ctl, board.start_loosen(), t + 30.0)
                loose = _stand(lb.control, ctl)
            finally:
                board.close()
    finally:
        lb.stop()
    # clamped legs barely give under the vehicle's weight on the pad; loose legs fold
    assert all(abs(a - h) < 3.0 for a, h in zip(clamped, held, strict=True)), (held, clamped)
    assert all(a < min(clamped) - 10.0 for a in loose), (clamped, loose)
    assert clamped[0] == clamped[1] and clamped[2] == clamped[3]  # one planar leg per real pair
