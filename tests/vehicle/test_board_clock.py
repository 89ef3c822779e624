"""In a flight the simulated leg board runs on the vehicle's clock (``--clock external``).

The rig's real processes: board, lock-stepped vehicle and the companion. After a flight
segment the vehicle is frozen (SIGSTOP), every message it sent is read, and the board's time is
compared with the vehicle's: the bounds are in vehicle time, so machine load cannot move them.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from slopelander.legs.driver import LegBoard, LegTimeout
from slopelander_sitl.legboard.control import BoardControl
from slopelander_sitl.rig import Rig
from slopelander_sitl.vehicle.launch import REPO, child_env
from slopelander_sitl.vehicle.legs_link import PERIOD_S

TICK_S = 1.0 / 400  # the vehicle's control tick
IMU_PERIOD_S = 1.0 / 200  # the rig's RAW_IMU stream: the newest stamp lags the vehicle by at most this
DT_S = 0.004  # the board's physics step


def _drain(rig: Rig) -> float:
    """Read everything the (stopped) vehicle sent; its newest time (s)."""
    last, quiet = rig.now, 0
    while quiet < 50:  # the bytes are already on the loopback socket; 50 empty reads in a row
        rig.link.poll()
        quiet = quiet + 1 if rig.now == last else 0
        last = rig.now
        time.sleep(0.002)
    return last


def test_the_board_keeps_the_vehicles_time_and_stands_still_without_it():
    with Rig(slope_deg=20.0, seed=5) as rig:
        assert rig.board.clock == "external"
        rig.set_legs(1.5, 1.5)
        rig.take_off(2.0)
        rig.wait(3.0)
        pid = rig.vehicle.proc.pid
        os.kill(pid, signal.SIGSTOP)
        try:
            seen = _drain(rig)
            assert seen > 5.0, seen
            with BoardControl(rig.board.control) as ctl:
                st = ctl.state()
                # the vehicle fed the board its time at its last exchange, at most one exchange
                # period (+ a tick) before its newest time; the companion saw that newest time
                # to within one IMU period
                clock = st["clock_s"]
                assert seen - PERIOD_S - TICK_S - 1e-6 <= clock <= seen + IMU_PERIOD_S + TICK_S, (seen, clock)
                assert clock - DT_S - 1e-9 < st["time_s"] <= clock + 1e-9, (clock, st["time_s"])
                # no vehicle time, no board time: the window is wall time, 4 s of a wall board at 8x
                time.sleep(0.5)
                assert ctl.state()["time_s"] == st["time_s"]
        finally:
            os.kill(pid, signal.SIGCONT)
        rig.vehicle.stop()
        rig.vehicle = None
        with BoardControl(rig.board.control) as ctl:
            held = ctl.state()["time_s"]
            time.sleep(0.3)
            assert ctl.state()["time_s"] == held  # the vehicle gone: the board holds its time


def test_a_bad_exchange_period_is_refused_by_name():
    for bad in ("0", "-5", "nan"):
        r = subprocess.run(
            [sys.executable, "-m", "slopelander_sitl.vehicle", "--legboard-period-ms", bad],
            capture_output=True,
            text=True,
            env=child_env(),
            cwd=REPO,
            timeout=60,
        )
        assert r.returncode == 2 and "--legboard-period-ms" in r.stderr, (bad, r.returncode, r.stderr)


# The companion stops echoing the vehicle's time for STALL_S of wall time, less than the
# lock-stepped vehicle's give-up (1 s, src/slopelander_sitl/vehicle/vehicle.py LOCKSTEP_GIVE_UP_S): the
# vehicle,
# and the board on its time, stand still, as they do in shorter spells on a loaded machine. The
# drivers count a silent board after SILENT_S (the shipped 1 s would need a stall past the give-up).
STALL_S = 0.5
SILENT_S = 0.25


def _poll_legs_only(legs: LegBoard) -> None:
    """Read the board for STALL_S without polling the MAVLink link (so without echoing)."""
    end = time.monotonic() + STALL_S
    while time.monotonic() < end:
        legs.poll()
        time.sleep(0.005)


def test_a_stalled_lock_step_is_a_silent_board_only_on_the_wall_clock():
    """What made a loaded run fail a flight test: a driver on the wall clock calls the board
    silent while the lock-step stands still. The rig's driver (``Rig.open_legs``, the rule of
    ``Session.open_legs``) measures on the vehicle's clock and rides it out."""
    with Rig(slope_deg=20.0, seed=6) as rig:
        rig.legs.close()
        rig.legs = None
        wall = LegBoard.open(rig.board.pty, calibration=rig.calibration, silence_timeout=SILENT_S)
        try:
            rig.wait(0.3)  # the lock-step runs; the board reports
            with pytest.raises(LegTimeout, match="silent"):
                _poll_legs_only(wall)
        finally:
            wall.close()
        legs = rig.open_legs()
        assert legs is rig.legs
        legs.silence_timeout = SILENT_S
        rig.wait(0.3)
        _poll_legs_only(legs)
        before = legs.status.received_at
        rig.wait(1.0)  # the companion echoes again: the vehicle and the board run on
        assert legs.status.received_at > before
