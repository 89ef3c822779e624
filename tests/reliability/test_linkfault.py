"""The fault-injecting MAVLink relay: each fault does what it says on a real link.

A pymavlink client talks to the simulated vehicle (a real process) through the relay (another
real process, steered through its control port)."""

from __future__ import annotations

import os
import random
import subprocess
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

import pytest
from pymavlink import mavutil

from slopelander_sitl.linkfault import LinkFaults, RelayControl
from slopelander_sitl.linkfault.faults import FaultConfigError, decide
from slopelander_sitl.vehicle.launch import REPO, child_env, free_port, start_vehicle

#: its tests share one link under faults (link): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("reliability/linkfault")

ROUTE_A = {"FRAME_CLASS": 1, "MOT_PWM_TYPE": 0, "MOT_PWM_MIN": 1525, "MOT_PWM_MAX": 2000}
#: frames on their way between the relay's count and the client when a count is taken
IN_FLIGHT = 10


# -- the decisions, no sockets ---------------------------------------------------------------
def test_drop_rate_matches_its_probability_and_a_seed_repeats_a_run() -> None:
    frame = bytes(range(40))
    f = LinkFaults(drop=0.3)
    a = [decide(frame, f, r).copies for r in [random.Random(7)] for _ in range(4000)]
    rng = random.Random(7)
    b = [decide(frame, f, rng).copies for _ in range(4000)]
    assert a == b
    assert 0.27 < a.count(0) / len(a) < 0.33


def test_a_corrupted_frame_keeps_its_header_and_differs_in_one_byte() -> None:
    rng = random.Random(1)
    for frame, header in ((b"\xfd" + bytes(range(39)), 10), (b"\xfe" + bytes(range(39)), 6)):
        for _ in range(200):
            d = decide(frame, LinkFaults(corrupt=1.0), rng)
            diff = [i for i in range(len(frame)) if d.data[i] != frame[i]]
            assert len(diff) == 1 and diff[0] >= header


@pytest.mark.parametrize(
    "bad", [{"drop": 1.5}, {"delay_s": -1.0}, {"jitter_s": float("nan")}, {"corrupt": "x"}]
)
def test_impossible_fault_settings_are_refused(bad: dict) -> None:
    with pytest.raises(FaultConfigError):
        LinkFaults().updated(bad)


def test_an_unknown_fault_setting_is_named() -> None:
    with pytest.raises(FaultConfigError, match="lose"):
        LinkFaults().updated({"lose": 0.1})


def test_the_relay_sends_each_frame_at_once_over_tcp() -> None:
    """Nagle's algorithm off on both of the relay's TCP legs: with it on, a small frame waited
    for the peer's delayed ACK, and a lock-stepped vehicle behind the relay ran at about real
    time whatever its speed (found by timing the soak: 1.1x at --speed 20, 7-8x without it)."""
    import socket

    from slopelander_sitl.linkfault.relay import Relay

    srv = socket.create_server(("127.0.0.1", 0))
    relay = Relay("tcp:127.0.0.1:0", f"tcp:127.0.0.1:{srv.getsockname()[1]}").start()
    try:
        client = socket.create_connection(("127.0.0.1", relay.port), timeout=5.0)
        srv.settimeout(5.0)
        upstream, _ = srv.accept()  # the relay connected on to the "vehicle"
        deadline = time.monotonic() + 5.0
        while len(relay._socks) < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
        tcp = [x for x in relay._socks if x.type == socket.SOCK_STREAM and x.fileno() >= 0]
        legs = [x for x in tcp if x.getsockopt(socket.SOL_SOCKET, socket.SO_ACCEPTCONN) == 0]
        assert len(legs) == 2, legs
        assert all(x.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) for x in legs)
        client.close()
        upstream.close()
    finally:
        relay.stop()
        srv.close()


# -- the relay between a client and the vehicle ------------------------------------------------
@pytest.fixture(scope="module")
def link():
    # at 4x real time: the tests count messages, and its streams come four times as fast
    v = start_vehicle(params=ROUTE_A, no_script=True, speed=4.0)
    port = free_port()
    relay = subprocess.Popen(
        [sys.executable, "-m", "slopelander_sitl.linkfault", "--listen", f"tcp:127.0.0.1:{port}",
         "--to", f"tcp:127.0.0.1:{v.port}", "--seed", "3"],
        stdout=subprocess.PIPE, text=True, env=child_env(), cwd=REPO,
    )  # fmt: skip
    ready = relay.stdout.readline().split()
    assert ready[:2] == ["linkfault", "ready"], ready
    ctl = RelayControl(int(ready[3].split("=")[1]))
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=255, source_component=190)
    try:
        assert conn.wait_heartbeat(timeout=15) is not None
        yield conn, ctl
    finally:
        conn.close()
        relay.terminate()
        relay.wait(5)
        v.stop()


@pytest.fixture
def clean(link):
    conn, ctl = link
    ctl.restore()
    ctl.set(drop=0.0, duplicate=0.0, reorder=0.0, corrupt=0.0, delay_s=0.0, jitter_s=0.0)
    drain(conn, 0.3)
    return conn, ctl


def drain(conn, seconds: float) -> list:
    """Every message (and bad frame) that arrives within ``seconds`` of wall time."""
    out, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        m = conn.recv_match(blocking=True, timeout=max(0.01, end - time.monotonic()))
        if m is not None:
            out.append(m)
    return out


def collect(conn, enough, timeout: float = 30.0) -> list:
    """Messages until ``enough(messages)`` holds (or the timeout): counts, not wall time, so a
    vehicle slowed by a loaded machine only makes the test take longer."""
    out, end = [], time.monotonic() + timeout
    while not enough(out) and time.monotonic() < end:
        m = conn.recv_match(blocking=True, timeout=0.1)
        if m is not None:
            out.append(m)
    return out


def heartbeats(msgs: list) -> list:
    return [m for m in msgs if m.get_type() == "HEARTBEAT"]


def test_a_clean_relay_passes_every_frame(clean) -> None:
    conn, ctl = clean
    before = ctl.stats()["down"]
    msgs = collect(conn, lambda got: len(got) > 40 and heartbeats(got))
    after = ctl.stats()["down"]
    assert len(heartbeats(msgs)) >= 1
    # every message came through the relay: as many frames as messages, give or take those the
    # relay had counted but the client not yet read when the count was taken (IN_FLIGHT)
    assert after["frames"] - before["frames"] + IN_FLIGHT >= len(msgs) > 40
    assert after["dropped"] == before["dropped"] and after["corrupted"] == before["corrupted"]
    assert not [m for m in msgs if m.get_type() == "BAD_DATA"]


def test_dropping_half_the_frames_halves_what_arrives(clean) -> None:
    conn, ctl = clean
    ctl.set(drop=0.5)
    drain(conn, 0.2)
    before = ctl.stats()["down"]
    msgs = collect(conn, lambda got: len(got) >= 100)
    after = ctl.stats()["down"]
    frames = after["frames"] - before["frames"]
    dropped = after["dropped"] - before["dropped"]
    assert 0.35 < dropped / frames < 0.65, (dropped, frames)
    # what arrived is what was not dropped (give or take the frames in flight at either end)
    assert abs(len(msgs) - (frames - dropped)) <= IN_FLIGHT, (len(msgs), frames, dropped)


def test_a_cut_silences_the_link_and_it_comes_back(clean) -> None:
    conn, ctl = clean
    ctl.cut(1.5)
    drain(conn, 0.2)  # frames already on their way
    assert drain(conn, 1.0) == []
    assert heartbeats(collect(conn, heartbeats))


def test_a_cut_for_good_lasts_until_restored(clean) -> None:
    conn, ctl = clean
    ctl.cut(None)
    drain(conn, 0.2)
    assert drain(conn, 2.5) == []
    assert ctl.stats()["cut"] is True
    ctl.restore()
    assert heartbeats(collect(conn, heartbeats))


def test_corrupted_frames_fail_the_receivers_crc(clean) -> None:
    conn, ctl = clean
    ctl.set(corrupt=1.0)
    drain(conn, 0.2)
    msgs = collect(conn, lambda got: len(got) > 20)
    good = [m for m in msgs if m.get_type() != "BAD_DATA"]
    assert good == [] and len(msgs) > 20


def test_duplicated_frames_arrive_twice_with_the_same_sequence_number(clean) -> None:
    conn, ctl = clean
    ctl.set(duplicate=1.0)
    drain(conn, 0.2)
    hb = heartbeats(collect(conn, lambda got: len(heartbeats(got)) >= 7))
    seqs = [m.get_seq() for m in hb]
    if seqs[0] != seqs[1]:
        seqs = seqs[1:]  # the first copy of the first pair came before the window
    pairs = seqs[:6]
    assert len(pairs) == 6 and pairs[0::2] == pairs[1::2], seqs
    assert len(set(pairs)) == 3, seqs


def test_a_delay_shows_in_the_round_trip(clean) -> None:
    conn, ctl = clean

    def round_trip() -> float:
        drain(conn, 0.05)
        t0 = time.monotonic()
        conn.mav.param_request_read_send(1, 1, b"ANGLE_MAX", -1)
        m = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=5)
        assert m is not None
        return time.monotonic() - t0

    round_trip()  # the link works undelayed
    ctl.set(delay_s=0.4)
    slow = round_trip()
    assert slow >= 0.8, slow  # 0.4 s each way (a lower bound: load can only add to it)


def test_the_control_port_refuses_a_bad_setting_with_its_reason(clean) -> None:
    _, ctl = clean
    with pytest.raises(FaultConfigError, match="drop"):
        ctl.set(drop=2.0)


# -- a lock-stepped vehicle behind the relay ---------------------------------------------------
def test_a_lockstep_cut_lasts_its_vehicle_seconds_and_the_vehicle_runs_in_real_time() -> None:
    """Without the relay's pacing a lock-stepped vehicle freezes during a cut (nobody echoes),
    then runs free as fast as it can after its give-up second: the cut's length in vehicle time
    would follow the machine's load (here: frozen for 1 s, then 1 s of vehicle time in a flash)."""
    from slopelander.controller.link import Link, mavlink

    v = start_vehicle(params=ROUTE_A, no_script=True, speed=0.0, lockstep=True)
    port = free_port()
    relay = subprocess.Popen(
        [sys.executable, "-m", "slopelander_sitl.linkfault", "--listen", f"tcp:127.0.0.1:{port}",
         "--to", f"tcp:127.0.0.1:{v.port}", "--lockstep"],
        stdout=subprocess.PIPE, text=True, env=child_env(), cwd=REPO,
    )  # fmt: skip
    link = None
    try:
        ready = relay.stdout.readline().split()
        assert ready[:2] == ["linkfault", "ready"], ready
        ctl = RelayControl(int(ready[3].split("=")[1]))
        link = Link(f"tcp:127.0.0.1:{port}", link_loss_s=60.0, lockstep=True)
        link.wait_autopilot(timeout_s=30.0)
        ask = link.request_stream(mavlink.MAVLINK_MSG_ID_RAW_IMU, 200)
        end = time.monotonic() + 10.0
        while not ask.done and time.monotonic() < end:
            link.poll()
            time.sleep(0.002)
        assert ask.ok
        t_run = link.clock.now()
        w_run = time.monotonic()
        while time.monotonic() - w_run < 0.5:
            link.poll()
            time.sleep(0.001)
        assert link.clock.now() - t_run > 0.2  # with the companion echoing, it runs (speed 0: flat out)
        for _ in range(50):  # let the frames in flight arrive, so the clock is the cut's start
            link.poll()
            time.sleep(0.001)
        before = link.clock.now()
        ctl.cut(2.0)
        w0 = time.monotonic()
        while link.clock.now() <= before + 0.1 and time.monotonic() - w0 < 30.0:
            link.poll()
            time.sleep(0.001)
        silent_wall = time.monotonic() - w0
        after = link.clock.now()
        # the first vehicle time after the cut: it lasted two vehicle seconds, and ended then
        assert 1.95 <= after - before <= 2.2, (before, after)
        # during it the vehicle ran no faster than the wall clock: its 50 ms lead over the echo,
        # and up to as much again between the newest time this link saw and the cut's start
        assert silent_wall >= (after - before) - 0.11, (silent_wall, before, after)
        assert ctl.stats()["cut"] is False
    finally:
        if link is not None:
            link.close()
        relay.terminate()
        relay.wait(10)
        v.stop()
