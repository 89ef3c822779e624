"""A real landing: the simulated vehicle with the on-board script and the simulated leg board as
processes, the companion's Lander over TCP MAVLink and a pseudo-terminal. About 50 s of wall time
(the vehicle's start compiles the model on a cold cache)."""

from __future__ import annotations

import time

import pytest

from slopelander.controller.config import load_config
from slopelander.controller.link import Link, mavlink
from slopelander.controller.runner import Lander
from slopelander.legs.calibration import load_calibration
from slopelander.legs.driver import LegBoard
from slopelander_sitl.legboard.runtime import silence_in_wall_time
from slopelander_sitl.vehicle.launch import REPO, start_legboard, start_vehicle
from tests.vehicle.conftest import ROUTE_A

SCRIPT = REPO / "firmware_params" / "scripts" / "slopelander.lua"


def wait(link: Link, h, seconds: float = 3.0) -> str:
    end = time.monotonic() + seconds
    while time.monotonic() < end and not h.done:
        link.poll()
        time.sleep(0.005)
    return h.state


@pytest.fixture
def airborne():
    # the vehicle at real time, as a real one flies; the board at 4x the wall clock: its legs
    # clamp in about 2.5 s, not the paper's 10 s of waiting
    lb = start_legboard(speed=4.0, config=silence_in_wall_time(4.0))
    v = start_vehicle(params=ROUTE_A, script=SCRIPT, speed=1.0, legboard_control=lb.control)
    link = Link(v.mavlink_url)
    legs = None
    try:
        link.wait_autopilot(10)
        for mid, hz in ((mavlink.MAVLINK_MSG_ID_RAW_IMU, 200), (mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR, 50)):
            assert wait(link, link.request_stream(mid, hz)) == "accepted"
        assert wait(link, link.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4)) == "accepted"
        assert wait(link, link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)) == "accepted"
        assert wait(link, link.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 3.0)) == "accepted"
        end = time.monotonic() + 20
        while time.monotonic() < end:
            link.poll()
            ds = link.last.get("DISTANCE_SENSOR")
            if ds is not None and ds.current_distance > 270:
                break
            time.sleep(0.005)
        else:
            pytest.fail("did not climb to 2.7 m")
        legs = LegBoard.open(lb.pty, calibration=load_calibration())
        yield link, legs
    finally:
        if legs is not None:
            legs.close()
        link.close()
        v.stop()
        lb.stop()


def test_lands_with_reflex_and_ends_disarmed(airborne, tmp_path):
    link, legs = airborne
    with (tmp_path / "landing.jsonl").open("w") as rec:
        lander = Lander(link, load_config(), (0.8, 1.5), legs=legs, record=rec)
        assert lander.run(40) == "LANDED", lander.machine.history
    seq = [h["to"] for h in lander.machine.history]
    assert seq == ["PRESET", "LEGS_WAIT", "CHECKS", "DESCEND", "ARMED", "CUT", "REVERSE", "SETTLED", "LANDED"]
    end = time.monotonic() + 5
    while time.monotonic() < end:
        lander.poll()
        hb = link.last["HEARTBEAT"]
        if not hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
            break
        time.sleep(0.01)
    assert not link.last["HEARTBEAT"].base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED, "still armed"
    assert link.last["DISTANCE_SENSOR"].current_distance < 30
