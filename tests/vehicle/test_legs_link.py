"""The vehicle and the simulated leg board as two processes: torques set over the serial link
with the LegBoard driver reach the vehicle's physics, and the vehicle's joint angles reach the
board while it stands on the pad."""

from __future__ import annotations

import time

from sitl.legboard.control import BoardControl
from sitl.vehicle.launch import start_legboard, start_vehicle
from slopelander.legs import LegBoard
from tests.vehicle.conftest import ROUTE_A


def _angles(control) -> list[float]:
    """Smallest angle per leg over 0.5 s: a loose leg springs back between the vehicle's
    50 Hz writes, so a single read may catch it extended."""
    out = [90.0] * 4
    with BoardControl(control) as c:
        for _ in range(25):
            out = [min(o, float(leg["angle_deg"])) for o, leg in zip(out, c.state()["legs"], strict=True)]
            time.sleep(0.02)
    return out


def test_torques_in_angles_out():
    lb = start_legboard(speed=4.0)  # board time 4x the wall clock: the legs clamp in about 2 s
    try:
        board = LegBoard.open(lb.pty)
        try:
            board.set_torques(uphill=2.3, downhill=2.3)
        finally:
            board.close()
        held = _angles(lb.control)
        v = start_vehicle(params=ROUTE_A, no_script=True, legboard_control=lb.control)
        try:
            time.sleep(1.5)
            clamped = _angles(lb.control)
        finally:
            assert v.stop() == 0
        board = LegBoard.open(lb.pty)
        try:
            board.loosen_all()
        finally:
            board.close()
        v = start_vehicle(params=ROUTE_A, no_script=True, legboard_control=lb.control)
        try:
            time.sleep(1.5)
            loose = _angles(lb.control)
        finally:
            v.stop()
    finally:
        lb.stop()
    # clamped legs barely give under the vehicle's weight on the pad; loose legs fold
    assert all(abs(a - h) < 3.0 for a, h in zip(clamped, held, strict=True)), (held, clamped)
    assert all(a < min(clamped) - 10.0 for a in loose), (clamped, loose)
    assert clamped[0] == clamped[1] and clamped[2] == clamped[3]  # one planar leg per real pair
