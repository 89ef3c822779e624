"""The server against a stand-in for ArduPilot over real UDP: the first-packet handshake, one
reply per frame, re-sent frames, restarts and bad datagrams."""

from __future__ import annotations

import itertools
import socket
import struct
import time

import pytest

from slopelander_sitl.json_physics.ardupilot_side import ArduPilotSide
from slopelander_sitl.json_physics.protocol import encode_servo_packet
from tests.json_physics.conftest import alt, fly

#: its tests share one physics server (pad_server): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("json_physics/lockstep")

KEYS = {"timestamp", "imu.gyro", "imu.accel_body", "position", "velocity", "attitude", "rng_1"}


def _nothing_pending(sock: socket.socket) -> bool:
    sock.settimeout(0.2)
    try:
        sock.recv(65000)
    except TimeoutError:
        return True
    return False


def test_first_packet_is_answered_at_its_sender(ap: ArduPilotSide) -> None:
    s = ap.update([1525] * 4)
    assert set(s) == KEYS
    assert ap.frame_counter == 1 and ap.resends == 0 and ap.rejected == 0
    assert s["timestamp"] == pytest.approx(1 / 1200, abs=1e-12)


@pytest.mark.parametrize("channels", [16, 32])
def test_one_reply_per_frame_in_lock_step(pad_server, channels: int) -> None:
    ap = ArduPilotSide(pad_server.port, channels=channels)
    try:
        stamps = [ap.update([1525] * 4)["timestamp"] for _ in range(600)]
        assert ap.frame_counter == 600 and ap.resends == 0
        assert ap.time_now_us == pytest.approx(0.5e6, abs=1.0)  # ArduPilot's clock moved by 600 frames
        steps = [b - a for a, b in itertools.pairwise(stamps)]
        assert min(steps) == pytest.approx(1 / 1200, rel=1e-6) and max(steps) == pytest.approx(
            1 / 1200, rel=1e-6
        )
        assert _nothing_pending(ap.sock)
        s = fly(ap, 2.0, 1.0)  # the motors of either packet form lift the vehicle
        assert alt(s) == pytest.approx(1.0, abs=0.1)
    finally:
        ap.close()


def test_the_frame_rate_sets_the_step(pad_server) -> None:
    ap = ArduPilotSide(pad_server.port, frame_rate=400)
    try:
        a = ap.update([1525] * 4)["timestamp"]
        b = ap.update([1525] * 4)["timestamp"]
        assert (a, b - a) == (pytest.approx(1 / 400), pytest.approx(1 / 400))
    finally:
        ap.close()


def test_a_lost_reply_is_sent_again_without_stepping_twice(ap: ArduPilotSide) -> None:
    for _ in range(10):
        ap.update([1525] * 4)
    before = ap.state["timestamp"]
    ap.drop_replies = 1
    t0 = time.monotonic()
    after = ap.update([1525] * 4)["timestamp"]
    assert ap.resends == 1 and time.monotonic() - t0 >= 1.0  # ArduPilot waited a second, re-sent
    assert after - before == pytest.approx(1 / 1200, rel=1e-9)
    assert ap.physics_resets == 0


def test_a_repeated_frame_gets_the_same_bytes(pad_server) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(5)
        pkt = encode_servo_packet(1200, 0, [1700] * 4 + [0] * 12)
        s.sendto(pkt, ("127.0.0.1", pad_server.port))
        first = s.recv(65000)
        s.sendto(pkt, ("127.0.0.1", pad_server.port))
        again = s.recv(65000)
        s.sendto(encode_servo_packet(1200, 1, [1700] * 4 + [0] * 12), ("127.0.0.1", pad_server.port))
        nxt = s.recv(65000)
    assert again == first and nxt != first


def test_frame_count_going_back_is_a_restart_and_resets_the_physics(ap: ArduPilotSide, pad_server) -> None:
    s = fly(ap, 2.0, 1.0)
    assert alt(s) > 0.8
    ap.frame_counter = 0  # ArduPilot restarted: it counts from 0 again
    s = ap.update([1525] * 4)
    assert ap.physics_resets == 1  # the timestamp went back: ArduPilot sees the physics reset
    assert s["timestamp"] == pytest.approx(1 / 1200) and abs(alt(s)) < 0.01
    assert "ArduPilot restarted: physics reset" in pad_server.stderr()


def test_a_new_ardupilot_starts_from_the_ground(pad_server) -> None:
    first = ArduPilotSide(pad_server.port)
    second = ArduPilotSide(pad_server.port)
    try:
        assert alt(fly(first, 2.0, 1.0)) > 0.8
        s = second.update([1525] * 4)
        assert s["timestamp"] == pytest.approx(1 / 1200) and abs(alt(s)) < 0.01
    finally:
        first.close()
        second.close()


def test_datagrams_that_are_not_servo_packets_get_no_reply(pad_server) -> None:
    bad = [
        b"hello",
        struct.pack("<HHI16H", 12345, 1200, 0, *[1500] * 16),
        struct.pack("<HHI16H", 18458, 0, 0, *[1500] * 16),
        encode_servo_packet(1200, 0, [1500] * 16)[:-2],
    ]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for raw in bad:
            s.sendto(raw, ("127.0.0.1", pad_server.port))
        assert _nothing_pending(s)
        s.settimeout(5)
        s.sendto(encode_servo_packet(1200, 0, [1500] * 16), ("127.0.0.1", pad_server.port))
        assert s.recv(65000).startswith(b'\n{"timestamp":')
    # reported with the reason, at most one line a second (a flood must not flood the log)
    err = pad_server.stderr()
    assert "ignored a datagram" in err and "shorter than its 8-byte header" in err
    assert err.count("ignored a datagram") == 1


def test_skipped_frame_counts_step_once_each(pad_server) -> None:
    """ArduPilot counts replies it consumed; a jump in the count (replies it lost) is one step."""
    stamps = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(5)
        for count in (0, 1, 5, 6):
            s.sendto(encode_servo_packet(1200, count, [1525] * 16), ("127.0.0.1", pad_server.port))
            stamps.append(float(s.recv(65000).split(b",")[0].split(b":")[1]))
    assert stamps == pytest.approx([k / 1200 for k in (1, 2, 3, 4)])
