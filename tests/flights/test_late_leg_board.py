"""A leg board whose bytes are late, as a loaded machine's kernel makes them: the simulation waits.

On a loaded machine Linux can hold a pseudo-terminal's bytes for seconds (its tty worker
unscheduled: ``slopelander_sitl/legboard/line.py``). The simulated vehicle runs on meanwhile
unless the companion's lock-step echo holds it for the board
(``slopelander/controller/link/lockstep.py``); the held vehicle's silence is then the
companion's own, not a lost link. Here the board's line is stalled for 2.5 s of wall time, on
both autopilots, while the vehicle hovers: the vehicle's time stands within the hold's slack of
the board's last word, the link is not lost and the board is not found silent. Without the hold
the same stall is a silent board (the test's own check that the stall bites).
"""

from __future__ import annotations

import time

import pytest

from slopelander.controller.link.lockstep import BOARD_SLACK_S
from slopelander.legs.errors import LegTimeout
from slopelander_sitl.legboard.control import BoardControl
from slopelander_sitl.rig import Rig
from tests.flights.conftest import AUTOPILOTS, autopilot_available

STALL_S = 2.5
#: vehicle seconds a simulator runs past the newest echo: the simulated vehicle's lead (50 ms),
#: ArduCopter's gate (0.25 s), each with an echo period (20 ms) and a frame
LEADS = {"sim": 0.05 + 0.02 + 0.01, "ardupilot": 0.25 + 0.02 + 0.01}


def stall_and_watch(rig: Rig) -> tuple[float, float, list[str], list[str]]:
    """Stall the board's line and keep polling the link and the board as a landing does; the
    vehicle time the stall began at, the most the vehicle's time ran past the board's last word,
    the link's losses and the board's silences."""
    ctl = BoardControl(rig.board.control)
    try:
        ctl.request(op="line_stall", seconds=STALL_S)
    finally:
        ctl.close()
    began = rig.now
    ahead, losses, silences = 0.0, [], []
    end = time.monotonic() + STALL_S + 1.5
    while time.monotonic() < end:
        rig.link.poll()
        if rig.link.lost:
            losses.append(rig.link.lost_why)
        if not silences:
            try:
                rig.legs.poll()
            except LegTimeout as exc:
                silences.append(str(exc))
        ahead = max(ahead, rig.now - rig.legs.accounted_until())
        time.sleep(0.002)
    return began, ahead, losses, silences


@pytest.fixture(params=AUTOPILOTS)
def hovering(request):
    autopilot = autopilot_available(request.param)
    with Rig(slope_deg=20.0, autopilot=autopilot, seed=7) as rig:
        rig.take_off(1.5)
        yield rig, autopilot


def test_a_stalled_leg_board_line_holds_the_vehicle_and_is_neither_silent_nor_a_lost_link(hovering):
    rig, autopilot = hovering
    began, ahead, losses, silences = stall_and_watch(rig)
    assert not losses, losses
    assert not silences, silences
    assert rig.link.lockstep.holds >= 1
    assert ahead <= BOARD_SLACK_S + LEADS[autopilot], (ahead, autopilot)
    # and the vehicle goes on once the board's bytes come (however slowly a loaded machine runs it)
    end = time.monotonic() + 30.0
    while rig.now - began <= BOARD_SLACK_S + LEADS[autopilot] and time.monotonic() < end:
        rig.poll()
        time.sleep(0.002)
    assert rig.now - began > BOARD_SLACK_S + LEADS[autopilot]
    assert rig.legs.poll() is not None


def test_without_the_hold_the_same_stall_reads_as_a_silent_board(hovering):
    rig, _ = hovering
    rig.link.lockstep.limit = None  # the echo no longer waits for the board
    _, ahead, losses, silences = stall_and_watch(rig)
    assert not losses, losses
    assert ahead > 1.0  # the board's 1 s silence limit passed on the vehicle's clock
    assert silences, "the stall went unnoticed: it did not hold the board's bytes"
