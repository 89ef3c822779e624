"""The companion's link keeps a lock-stepped simulated vehicle (a real process) in step: the
vehicle never runs more than its 50 ms lead ahead of the newest time the link has seen, so a
flight in simulation does not depend on how fast the machine runs the companion; nor, with the
echo held for it, on how late the leg board's bytes are."""

from __future__ import annotations

import time

from slopelander.controller.link import Link, lockstep, mavlink
from slopelander.controller.link.lockstep import PERIOD_S as TIMESYNC_PERIOD_S
from slopelander_sitl.vehicle.launch import start_vehicle
from tests.vehicle.conftest import ROUTE_A

LEAD_S = 0.05  # the vehicle's lock-step lead (src/slopelander_sitl/vehicle/vehicle.py)
TICK_S = 0.0025  # one control tick: the vehicle checks the lead between ticks
GIVE_UP_S = 1.0  # wall seconds without an echo before the vehicle runs free


def poll_for(link: Link, wall_s: float) -> None:
    end = time.monotonic() + wall_s
    while time.monotonic() < end:
        link.poll()
        time.sleep(0.001)


def test_the_vehicle_waits_for_the_links_echo():
    v = start_vehicle(params=ROUTE_A, no_script=True, speed=0.0, lockstep=True)
    link = Link(v.mavlink_url, link_loss_s=5.0, lockstep=True)
    try:
        link.wait_autopilot(timeout_s=30.0)
        ask = link.request_stream(mavlink.MAVLINK_MSG_ID_RAW_IMU, 200)  # the landing's clock source
        end = time.monotonic() + 10.0
        while not ask.done and time.monotonic() < end:
            poll_for(link, 0.01)
        assert ask.ok, ask.state
        poll_for(link, 0.5)
        assert link.clock.known
        jumps = []
        for _ in range(5):
            before = link.clock.now()
            t0 = time.monotonic()
            time.sleep(0.3)  # the companion looks away; a free-running vehicle would run on
            link.poll()  # what arrived meanwhile (this poll's echo lets the vehicle go on)
            paused = time.monotonic() - t0
            if paused > 0.8 * GIVE_UP_S:  # the machine stalled us past the vehicle's patience
                continue
            jumps.append(link.clock.now() - before)
        assert jumps, "the test process never got a pause shorter than the vehicle's give-up time"
        # the newest echo is at most one echo period older than `before`; the vehicle stops once it
        # is LEAD_S ahead of it, within a control tick
        for jump in jumps:
            assert jump <= LEAD_S + TIMESYNC_PERIOD_S + TICK_S + 1e-6, jumps
        # and while the link polls, the vehicle does run on
        before = link.clock.now()
        poll_for(link, 0.5)
        assert link.clock.now() - before > 0.1
    finally:
        link.close()
        v.stop()


def held_vehicle() -> tuple:
    """A lock-stepped vehicle streaming its IMU (the landing's clock source) to a link."""
    v = start_vehicle(params=ROUTE_A, no_script=True, speed=0.0, lockstep=True, give_up_s=30.0)
    link = Link(v.mavlink_url, link_loss_s=1.0, lockstep=True)
    try:
        link.wait_autopilot(timeout_s=30.0)
        ask = link.request_stream(mavlink.MAVLINK_MSG_ID_RAW_IMU, 200)
        end = time.monotonic() + 10.0
        while not ask.done and time.monotonic() < end:
            poll_for(link, 0.01)
        assert ask.ok, ask.state
        poll_for(link, 0.3)
    except BaseException:
        link.close()
        v.stop()
        raise
    return v, link


def test_the_echo_holds_for_a_board_not_heard_from_and_the_held_silence_is_not_a_lost_link(monkeypatch):
    """A limit (the leg board's accounted time) holds the echo, and with it the vehicle, at the
    limit plus the slack; the silence of the held vehicle is not counted; a hold ends after
    HOLD_MAX_S of local time, and the silence counts again from there."""
    monkeypatch.setattr(lockstep, "HOLD_MAX_S", 2.0)  # shorter than the 5 s of a flight
    v, link = held_vehicle()
    try:
        heard = link.clock.now()  # the board's last word, as far as the limit says
        link.lockstep.limit = lambda: heard
        poll_for(link, 1.5)  # longer than the link's 1 s loss limit
        assert link.lockstep.holding
        assert not link.lost, link.lost_why
        held_at = link.clock.now()
        assert held_at <= heard + lockstep.BOARD_SLACK_S + LEAD_S + TIMESYNC_PERIOD_S + TICK_S + 1e-6
        poll_for(link, 1.0)  # past HOLD_MAX_S: the hold ends, the vehicle runs on
        assert not link.lockstep.holding
        assert link.clock.now() > held_at + 0.1
        assert not link.lost, link.lost_why
        link.lockstep.limit = None
    finally:
        link.close()
        v.stop()


def test_before_holding_the_companion_reads_what_its_board_has_in_flight():
    """The catch-up hook (the leg board's read that waits for the bytes the kernel holds) runs
    before the echo holds; when that brings the board's word up to date, nothing is held."""
    v, link = held_vehicle()
    try:
        heard, calls = [link.clock.now()], []

        def catch_up() -> None:
            calls.append(link.clock.now())
            heard[0] = link.clock.now()  # what was in flight, now read

        link.lockstep.limit = lambda: heard[0]
        link.lockstep.catch_up = catch_up
        before = link.clock.now()
        poll_for(link, 1.0)
        assert calls and link.lockstep.holds == 0
        assert link.clock.now() > before + lockstep.BOARD_SLACK_S + 0.1  # it ran on
    finally:
        link.close()
        v.stop()
