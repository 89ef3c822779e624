"""Frames dropped by message id before decoding: MAVLink 2, signed, MAVLink 1, noise, split reads,
and a real UDP link that decodes only the landing's messages."""

from __future__ import annotations

import socket
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink import mavutil
from pymavlink.dialects.v10 import ardupilotmega as mav1
from pymavlink.dialects.v20 import ardupilotmega as mav2

from slopelander.controller.link import LANDING_MESSAGES, Link, LinkError, message_ids
from slopelander.controller.link.frames import FrameFilter

KEY = bytes(range(32))


def encoder(module, signed: bool = False):
    m = module.MAVLink(None, srcSystem=1, srcComponent=1)
    if signed:
        m.signing.secret_key = KEY
        m.signing.link_id = 3
        m.signing.sign_outgoing = True
        m.signing.timestamp = 1000
    return m


def frames(module, signed: bool = False) -> list[tuple[int, bytes]]:
    """(msgid, wire bytes) of a mix of messages, the long HIGHRES_IMU among them."""
    enc = encoder(module, signed)
    M = module
    msgs = [
        M.MAVLink_heartbeat_message(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3, 3),
        M.MAVLink_raw_imu_message(1_000_000, 1, 2, -1000, 0, 0, 0, 0, 0, 0),
        M.MAVLink_distance_sensor_message(1000, 20, 700, 150, 0, 1, 25, 0),
        M.MAVLink_timesync_message(5, 6),
        M.MAVLink_raw_imu_message(1_005_000, 3, 4, -1001, 0, 0, 0, 0, 0, 0),
    ]
    if module is mav2:
        msgs.insert(2, M.MAVLink_highres_imu_message(1_000_000, *[0.5] * 13, 0x3F))
        msgs.insert(5, M.MAVLink_highres_imu_message(1_005_000, *[0.25] * 13, 0x3F))
    return [(m.get_msgId(), bytes(m.pack(enc))) for m in msgs]


def decode(module, data: bytes, signed: bool = False):
    dec = module.MAVLink(None)
    dec.robust_parsing = True
    if signed:
        dec.signing.secret_key = KEY
    return dec.parse_buffer(data) or []


KEEP = message_ids(["HEARTBEAT", "RAW_IMU", "DISTANCE_SENSOR"])


@pytest.mark.parametrize("module,signed", [(mav2, False), (mav2, True), (mav1, False)])
def test_kept_frames_pass_whole_and_decode_the_others_are_dropped(module, signed):
    fr = frames(module, signed)
    f = FrameFilter(KEEP)
    out = f.feed(b"".join(b for _, b in fr))
    assert out == b"".join(b for i, b in fr if i in KEEP)
    got = decode(module, out, signed)
    assert [m.get_type() for m in got] == ["HEARTBEAT", "RAW_IMU", "DISTANCE_SENSOR", "RAW_IMU"]
    assert got[-1].xacc == 3 and got[-1].time_usec == 1_005_000
    if signed:
        assert all(m.get_signed() for m in got)
    assert f.dropped == len(fr) - 4 and f.passed == 4


@pytest.mark.parametrize("module", [mav2, mav1])
def test_frames_cut_anywhere_across_reads_come_out_the_same(module):
    fr = frames(module)
    wire = b"".join(b for _, b in fr)
    expected = b"".join(b for i, b in fr if i in KEEP)
    for step in (1, 2, 3, 7, 11, 40):
        f = FrameFilter(KEEP)
        out = b"".join(f.feed(wire[i : i + step]) for i in range(0, len(wire), step))
        assert out == expected, step


def test_noise_is_dropped_and_counted_and_the_frame_after_it_decodes():
    fr = frames(mav2)
    noise = b"\x00\x11hello\x22"
    f = FrameFilter(KEEP)
    out = f.feed(noise + fr[1][1])
    assert out == fr[1][1] and f.noise == len(noise)
    assert [m.get_type() for m in decode(mav2, out)] == ["RAW_IMU"]


@pytest.mark.parametrize("module", [mav2, mav1])
@pytest.mark.parametrize("noise", [b"\xfd", b"\xfe", b"\xfd\xff", b"\xfe\x40\x00", b"\x00\xfd\x30\x00\x00"])
def test_one_magic_byte_of_noise_does_not_swallow_the_good_frames_after_it(module, noise):
    """A lone start byte (a serial line's noise) followed by a length byte: trusting that length
    skipped the good frames that followed; the CRC says it is no frame."""
    fr = frames(module)
    f = FrameFilter(KEEP)
    out = f.feed(noise + b"".join(b for _, b in fr))
    got = [m.get_msgbuf() for m in decode(module, out) if m.get_type() != "BAD_DATA"]
    assert got == [b for i, b in fr if i in KEEP]  # every good frame decodes
    assert out == b"".join(b for i, b in fr if i in KEEP)  # and nothing but them is passed on
    assert f.noise == len(noise)


def test_a_kept_frame_with_a_bad_crc_is_noise_and_the_next_frame_still_passes():
    fr = frames(mav2)
    raw = bytearray(fr[1][1])
    raw[-1] ^= 0xFF
    f = FrameFilter(KEEP)
    out = f.feed(bytes(raw) + fr[3][1])
    assert out == fr[3][1] and f.noise == len(raw)
    assert [m.get_type() for m in decode(mav2, out)] == ["DISTANCE_SENSOR"]


def test_a_signed_kept_frame_with_a_wrong_key_is_refused():
    out = FrameFilter(KEEP).feed(frames(mav2, signed=True)[1][1])
    dec = mav2.MAVLink(None)
    dec.robust_parsing = True
    dec.signing.secret_key = bytes(32)  # not the sender's
    assert [m.get_type() for m in dec.parse_buffer(out) or []] == ["BAD_DATA"]


def test_bad_filter_settings_are_refused():
    with pytest.raises(ValueError, match="no message id"):
        FrameFilter([])
    with pytest.raises(LinkError, match="NOT_A_MESSAGE"):
        message_ids(["HEARTBEAT", "NOT_A_MESSAGE"])


def test_udp_link_decodes_only_the_landing_messages():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    link = Link(f"udpin:127.0.0.1:{port}", decode=LANDING_MESSAGES)
    peer = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{port}", source_system=7, source_component=1, dialect="ardupilotmega"
    )
    try:
        deadline = time.monotonic() + 20.0  # generous: only a stalled machine comes near it
        usec = 1_000_000
        while "RAW_IMU" not in link.last and time.monotonic() < deadline:
            peer.mav.heartbeat_send(mav2.MAV_TYPE_QUADROTOR, mav2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3)
            peer.mav.highres_imu_send(usec, *[0.5] * 13, 0x3F)
            peer.mav.raw_imu_send(usec, 1, 2, -1000, 0, 0, 0, 0, 0, 0)
            usec += 5000
            link.wait_readable(0.05)
            link.poll()
        assert "RAW_IMU" in link.last and "HEARTBEAT" in link.last
        assert "HIGHRES_IMU" not in link.last
        assert link.filter.dropped > 0
        assert link.clock.usec >= 1_000_000  # the kept IMU still drives the vehicle clock
    finally:
        link.close()
        peer.close()


_GOOD = frames(mav2) + frames(mav2, signed=True) + frames(mav1)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from(range(len(_GOOD))), st.binary(max_size=12)),
        min_size=1,
        max_size=12,
    ),
    st.lists(st.integers(min_value=1, max_value=64), min_size=1, max_size=8),
    st.binary(min_size=1, max_size=4).map(lambda b: b"\xfd" + b),  # a start byte begins the noise
)
def test_noise_bytes_between_good_frames_never_lose_a_good_frame(parts, cuts, lead):
    """Any bytes between good frames (start bytes among them), read in any pieces: every kept
    good frame comes out, whole and in order, and nothing else."""
    wire, want = bytearray(lead), []
    for k, noise in parts:
        msgid, raw = _GOOD[k]
        wire += raw + noise
        if msgid in KEEP:
            want.append(raw)
    f = FrameFilter(KEEP)
    out, i, c = [], 0, 0
    while i < len(wire):
        step = cuts[c % len(cuts)]
        out.append(f.feed(bytes(wire[i : i + step])))
        i, c = i + step, c + 1
    assert b"".join(out) == b"".join(want)


def test_without_fastcrc_pymavlinks_python_crc_gives_the_same_frames(monkeypatch):
    from pymavlink.generator import mavcrc

    fr = frames(mav2)
    wire = b"\xfd\x07" + b"".join(b for _, b in fr)
    fast = FrameFilter(KEEP).feed(wire)
    monkeypatch.setattr(mavcrc, "mcrf4xx", None)  # what pymavlink does when fastcrc is missing
    assert FrameFilter(KEEP).feed(wire) == fast == b"".join(b for i, b in fr if i in KEEP)
