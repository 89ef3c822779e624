"""A leg board process that is killed and started again on the same port: the landing loop
reconnects it between landings, not during one (real board processes, a real pty, real UDP)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from slopelander.controller.link import Link
from slopelander.controller.runner import Lander
from slopelander.legs.calibration import load_calibration
from slopelander.legs.driver import LegBoard
from slopelander_sitl.legboard.runtime import silence_in_wall_time
from slopelander_sitl.rig import config
from slopelander_sitl.vehicle.launch import REPO, child_env

mavlink = mavutil.mavlink
HANG_S = 60.0  # only a bound against a hung test: every decision below runs on vehicle time


def start_board(link: Path) -> subprocess.Popen:
    config = link.with_name("config.json")
    config.write_text(json.dumps(silence_in_wall_time(20.0)))
    cmd = ["--link", str(link), "--speed", "20", "--config", str(config)]
    proc = subprocess.Popen(
        [sys.executable, "-m", "slopelander_sitl.legboard", *cmd],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=child_env(),
        cwd=REPO,
    )
    assert proc.stdout.readline().startswith("legboard ready")
    return proc


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
    proc.wait(timeout=10)
    proc.stdout.close()


class Autopilot:
    """Heartbeats and SYSTEM_TIME over real UDP. Its clock runs in real time, as a real
    autopilot's does next to a real leg board (the board process's status period is real time)."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=1, source_component=1, dialect="ardupilotmega"
        )
        self.ms = 1000
        self._t0 = time.monotonic()

    def tick(self) -> None:
        self.ms = 1000 + int((time.monotonic() - self._t0) * 1000)
        self.conn.mav.heartbeat_send(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 1, 4, mavlink.MAV_STATE_ACTIVE
        )
        self.conn.mav.system_time_send(0, self.ms)


def free_port() -> int:
    import socket

    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def run(lander: Lander, ap: Autopilot, until, vehicle_s: float) -> bool:
    """Tick the autopilot and poll the lander until ``until()`` or ``vehicle_s`` of vehicle time."""
    end = lander.link.clock.now() + vehicle_s
    hang = time.monotonic() + HANG_S
    while time.monotonic() < hang:
        ap.tick()
        lander.link.wait_readable(0.02)
        lander.poll()
        if until():
            return True
        if lander.link.clock.known and lander.link.clock.now() >= end:
            return False
    raise AssertionError("hung")


@pytest.fixture
def setup(tmp_path):
    port = free_port()
    link = Link(f"udpin:127.0.0.1:{port}")
    ap = Autopilot(port)
    path = tmp_path / "legs"
    procs = [start_board(path)]
    legs = LegBoard.open(str(path), calibration=load_calibration())
    # a board silent for 5 s is lost: generous against a loaded machine stalling the board process
    cfg = config(legs={"board_silent_s": 5.0})
    lander = Lander(link, cfg, (1.1, 1.1), legs=legs)
    try:
        assert run(lander, ap, lambda: link.info is not None and link.clock.now() > 1.1, 5.0)
        yield lander, ap, path, procs
    finally:
        legs.close()
        link.close()
        ap.conn.close()
        for p in procs:
            stop(p)


def test_a_board_back_between_landings_is_reconnected_and_takes_a_preset(setup):
    lander, ap, path, procs = setup
    lander.machine.transition("LANDED", "test: on the ground between landings", lander.inputs())
    board = lander.board
    stop(procs[0])  # the board vanishes: its port closes
    assert run(lander, ap, lambda: lander.legs is None, 8.0), "the lost board was not noticed"
    assert not os.path.exists(path)  # the dangling link of a dead board: nothing to open yet
    assert lander.inputs().legs_fault
    procs.append(start_board(path))  # the same port comes back
    assert run(lander, ap, lambda: lander.legs is not None, 10.0), lander.ctx.marks
    assert lander.legs is board and board.connected and board.info is not None
    assert lander.inputs().legs_fault is None
    lander.act.set_legs(1.3, 1.3)  # usable again: a preset goes through to the new process
    assert lander.act.leg_op is not None, lander.act.leg_error
    assert run(lander, ap, lambda: lander.act.leg_op is None or lander.act.leg_op.done, 30.0)
    assert lander.act.leg_op is not None, lander.ctx.marks
    op = lander.act.leg_op
    assert op.exception() is None
    # what each leg held when the preset was done; the status may have moved on since: at 20x a
    # loaded machine's 0.5 s pause is the board's 10 s companion silence, and a HOLDING leg stops
    assert all(r.converged for r in op.results.values()), op.results
    assert [op.results[i].achieved for i in range(4)] == pytest.approx([1.3] * 4, abs=0.15)


def test_a_board_back_during_a_landing_waits_for_the_landing_to_end(setup):
    lander, ap, path, procs = setup
    lander.machine.transition("TAKEOFF", "test: leaving the roof", lander.inputs())
    stop(procs[0])
    assert run(lander, ap, lambda: lander.legs is None, 8.0)
    procs.append(start_board(path))
    # many reconnect periods with the port back: the landing's failure policy holds, no reconnect
    periods = 3 * lander.cfg["legs.reconnect_s"]
    assert not run(lander, ap, lambda: lander.legs is not None, periods + 0.5)
    assert lander.machine.name == "TAKEOFF"  # after contact a leg failure is ignored (failsafes.md)
    lander.machine.transition("READY", "test: landing over", lander.inputs())
    assert run(lander, ap, lambda: lander.legs is not None, 10.0), lander.ctx.marks


def test_a_new_landing_with_a_board_that_failed_before_reconnects_it_first(setup):
    lander, ap, path, procs = setup
    lander.machine.transition("LANDED", "test", lander.inputs())
    stop(procs[0])
    assert run(lander, ap, lambda: lander.legs is None, 8.0)
    procs.append(start_board(path))
    nxt = Lander(lander.link, lander.cfg, (1.1, 1.1), legs=lander.board)
    assert nxt.legs is None  # closed by the failure
    assert run(nxt, ap, lambda: nxt.legs is not None, 10.0), nxt.ctx.marks
    assert "leg failure" not in " ".join(h["reason"] for h in nxt.machine.history)
