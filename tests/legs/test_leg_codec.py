"""The shared codec: round trips, garbage, bit flips, truncation, resynchronisation."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from slopelander.legs import codec, messages
from slopelander.legs.framing import MAX_ENCODED, cobs_decode, cobs_encode, crc32
from slopelander.legs.messages import N_LEGS, FaultCode, LegState

u8 = st.integers(0, 255)
mask = st.integers(1, 15)
four = st.tuples(*[st.integers(0, 1000)] * N_LEGS)


@st.composite
def leg_report(draw):
    state = draw(st.sampled_from(LegState))
    fault = draw(st.sampled_from(list(FaultCode)[1:])) if state is LegState.FAULT else (FaultCode.NONE)
    return messages.LegReport(
        state,
        fault,
        draw(st.integers(-2000, 2000)),
        draw(st.integers(0, 1000)),
        draw(st.integers(0, 3750)),
    )


any_message = st.one_of(
    st.builds(messages.Hello, st.integers(1, 255), st.integers(0, 65535)),
    st.builds(messages.SetFriction, mask, four),
    st.builds(messages.Loosen, mask),
    st.builds(messages.SetAngle, mask, st.tuples(*[st.integers(0, 3750)] * N_LEGS)),
    st.builds(messages.Stop, mask),
    st.just(messages.Query()),
    st.just(messages.Keepalive()),
    st.builds(
        messages.HelloReply,
        st.just(messages.PROTOCOL_VERSION),
        st.integers(1, 255),
        st.integers(0, 3),
        st.integers(1, 255),
        st.integers(0, 2**32 - 1),
        st.binary(min_size=8, max_size=8),
        st.integers(0, 65535),
    ),
    st.builds(messages.Ack, u8, st.integers(1, 7)),
    st.builds(messages.Nak, u8, st.integers(1, 7), st.integers(1, 6)),
    st.builds(
        messages.Status, st.integers(0, 2**32 - 1), u8, st.integers(0, 1), st.tuples(*[leg_report()] * N_LEGS)
    ),
)


def test_crc_is_crc32_ieee():
    assert crc32(b"123456789") == 0xCBF43926


def test_every_message_type_is_covered():
    seen = {
        messages.type_of(m)
        for m in (
            messages.Hello(),
            messages.SetFriction(1, (0,) * 4),
            messages.Loosen(1),
            messages.SetAngle(1, (0,) * 4),
            messages.Stop(1),
            messages.Query(),
            messages.Keepalive(),
            messages.HelloReply(messages.PROTOCOL_VERSION, 4, 0, 64, 0),
            messages.Ack(0, 1),
            messages.Nak(0, 1, 1),
            messages.Status(0, 0, 0, (messages.LegReport(LegState.LOOSE, FaultCode.NONE, 0, 0, 0),) * 4),
        )
    }
    assert seen == set(messages.MsgType)


@given(any_message, u8)
def test_round_trip(msg, seq):
    data = codec.encode(msg, seq)
    assert data.endswith(b"\x00") and b"\x00" not in data[:-1]
    assert len(data) <= MAX_ENCODED + 1
    (frame,) = codec.Decoder().feed(data)
    assert frame.message == msg and frame.seq == seq


@given(st.binary(max_size=300))
def test_cobs_round_trip(raw):
    if len(raw) < 254:
        assert cobs_decode(cobs_encode(raw)) == raw


@given(st.lists(st.binary(max_size=200), max_size=20))
def test_random_bytes_never_crash_and_every_reject_is_counted(chunks):
    dec = codec.Decoder()
    for chunk in chunks:
        for frame in dec.feed(chunk):
            assert isinstance(frame, codec.Frame)
    assert dec.rejects.total() >= 0
    assert dec.accepted <= sum(len(c) for c in chunks)


@given(any_message, u8, st.data())
def test_single_bit_flips_are_never_accepted(msg, seq, data):
    enc = codec.encode(msg, seq)
    pos = data.draw(st.integers(0, len(enc) - 2))  # any byte but the delimiter
    bit = data.draw(st.integers(0, 7))
    bad = bytearray(enc)
    bad[pos] ^= 1 << bit
    dec = codec.Decoder()
    assert dec.feed(b"\x00" + bytes(bad)) == []
    assert dec.rejects.total() >= 1


@given(any_message, u8, st.data())
def test_truncated_frames_are_rejected_and_the_next_frame_decodes(msg, seq, data):
    enc = codec.encode(msg, seq)
    cut = data.draw(st.integers(1, len(enc) - 2))
    good = codec.encode(messages.Query(), 7)
    dec = codec.Decoder()
    frames = dec.feed(enc[:cut] + b"\x00" + good)
    assert [f.message for f in frames] == [messages.Query()]
    assert dec.rejects.total() == 1


@given(any_message, any_message, st.data())
def test_interleaved_frames_are_rejected_then_resynchronised(a, b, data):
    ea, eb = codec.encode(a, 1), codec.encode(b, 2)
    cut = data.draw(st.integers(1, len(ea) - 2))
    tail = codec.encode(messages.Stop(5), 3)
    dec = codec.Decoder()
    frames = dec.feed(ea[:cut] + eb + ea[cut:] + tail)
    assert [f.message for f in frames] == [messages.Stop(5)]
    assert dec.rejects.total() == 2


def test_oversize_frames_are_dropped_until_the_next_delimiter():
    dec = codec.Decoder()
    frames = dec.feed(b"\x01" * 500 + b"\x00" + codec.encode(messages.Loosen(3), 9))
    assert [f.message for f in frames] == [messages.Loosen(3)]
    assert dec.rejects.oversize == 1


def test_bytes_arriving_one_at_a_time_decode():
    data = b"".join(codec.encode(messages.Loosen(m), m) for m in range(1, 16))
    dec = codec.Decoder()
    frames = [f for i in range(len(data)) for f in dec.feed(data[i : i + 1])]
    assert [f.message.mask for f in frames] == list(range(1, 16))


def test_unknown_type_and_bad_length_and_bad_values_are_counted():
    from slopelander.legs.framing import encode_frame

    dec = codec.Decoder()
    dec.feed(encode_frame(0x42, 0, b""))  # unknown type
    dec.feed(encode_frame(messages.MsgType.LOOSEN, 0, b"\x01\x02"))  # wrong length
    dec.feed(encode_frame(messages.MsgType.LOOSEN, 0, b"\x30"))  # legs 4, 5 do not exist
    dec.feed(encode_frame(messages.MsgType.SET_ANGLE, 0, b"\x01" + b"\xff\xff" * 4))
    r = dec.rejects
    assert (r.unknown_type, r.payload_length, r.bad_value) == (1, 1, 2)
    assert dec.accepted == 0


def test_mutation_run_accepts_no_corrupt_frame():
    """A short, seeded run of the benchmark (the full 10⁶ run is the benchmark itself)."""
    spec = importlib.util.spec_from_file_location(
        "codec_fuzz", Path(__file__).resolve().parents[2] / "benchmarks" / "codec_fuzz.py"
    )
    fuzz = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fuzz)
    r = fuzz.run(20_000, seed=1)
    assert r["accepted_corrupt"] == 0
    assert sum(r["rejects"].values()) > 0.8 * r["mutated_frames"]


def test_a_hello_reply_of_another_version_is_named_not_just_rejected():
    """A version-2 board answers HELLO_REPLY in its own 8-byte layout: the decoder drops it
    (wrong length) but keeps its version, so the driver can say what the board speaks."""
    from slopelander.legs.framing import encode_frame

    old = encode_frame(messages.MsgType.HELLO_REPLY, 0, bytes((2, 4, 3, 64)) + (1234).to_bytes(4, "little"))
    dec = codec.Decoder()
    assert dec.feed(old) == [] and dec.rejects.payload_length == 1
    assert dec.foreign_version == 2
    # a board of a later version with this version's layout decodes; the driver compares it
    (frame,) = dec.feed(codec.encode(messages.HelloReply(9, 4, 0, 64, 0), 1))
    assert frame.message.version == 9


def test_the_table_crc_is_the_same_crc():
    """The shared module's fallback, for a MicroPython build without binascii.crc32."""
    from slopelander.legs import wire

    for data in (b"", b"123456789", bytes(range(256)) * 3):
        assert wire.crc32_table(data) == wire.crc32(data)
