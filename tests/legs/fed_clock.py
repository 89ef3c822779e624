"""A simulated leg board on a fed clock (``--clock external``), driven by a test without a vehicle.

Such a board stands still between the times it is fed: a test feeds it a clamp or a loosening at
once, then a vehicle whose time is behind the board's holds it still while writing its joint
angles, so what the test reads afterwards is what the vehicle wrote (on the wall clock the
board's reset spring moves a loose leg at about 700 deg a second between the vehicle's writes).
"""

from __future__ import annotations

from slopelander.legs import LegBoard
from slopelander.legs.driver import Operation
from slopelander_sitl.legboard.control import BoardControl
from slopelander_sitl.legboard.feeding import wait_for_driver

STEP_S = 0.1


def board_time(board: LegBoard, ctl: BoardControl) -> None:
    """Measure ``board``'s timeouts on the board's own time from now on."""
    board.set_clock(lambda: ctl.state()["time_s"])


def feed_until_done(board: LegBoard, ctl: BoardControl, op: Operation, limit_s: float) -> float:
    """Feed the board time in ``STEP_S`` steps until ``op`` is done; the board time then."""
    t = ctl.state()["time_s"]
    while op.check() is None:
        assert t < limit_s, f"{op.kind} not done at board time {t:.1f} s"
        wait_for_driver(board, t)  # no faster than the driver hears the board
        t = ctl.advance(t + STEP_S)["time_s"]
        board.poll()
    return t
