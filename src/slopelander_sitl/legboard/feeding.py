"""Feeding a board on the external clock no faster than the companion hears it.

Whoever feeds a simulated board its time (the calibration bench, a test stepping a clamp) runs
that time on the companion's driver too. A loaded machine can hold the pseudo-terminal's bytes
for seconds (``slopelander_sitl/legboard/line.py``), and time fed meanwhile reads as a silent board
or an unanswered command. So, as the lock-step echo does for a flight
(``slopelander/controller/link/lockstep.py``), the feeder waits until the driver has accounted for
the board up to a slack before the time it feeds.
"""

from __future__ import annotations

import time

from slopelander.controller.link.lockstep import BOARD_SLACK_S, HOLD_MAX_S
from slopelander.legs import LegBoard


def wait_for_driver(
    driver: LegBoard, now: float, ahead_s: float = BOARD_SLACK_S, hold_max_s: float = HOLD_MAX_S
) -> None:
    """Poll ``driver`` until it has accounted for the board up to ``ahead_s`` before ``now`` (its
    clock's time), at most ``hold_max_s`` of wall time (a board really gone is then found silent)."""
    give_up = time.monotonic() + hold_max_s
    while time.monotonic() < give_up:
        until = driver.accounted_until()
        if until is None or now - until <= ahead_s:
            return
        driver.catch_up()  # waiting for what the kernel holds costs nothing here: we wait anyway
        driver.poll()
        time.sleep(0.001)
