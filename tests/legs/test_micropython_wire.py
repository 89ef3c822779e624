"""The shared protocol module on the real MicroPython: the firmware's framing, CRC, layouts and
range checks are the driver's, byte for byte, on both interpreters."""

from __future__ import annotations

import json
import random

from slopelander.legs import codec, messages, wire
from slopelander.legs.messages import FaultCode, LegState
from tests.legs.micropython_runner import needs_micropython, run

pytestmark = needs_micropython


def _sample_messages(rng: random.Random) -> list:
    legs = tuple(
        messages.LegReport(LegState(s), FaultCode(f), c, t, a)
        for s, f, c, t, a in (
            (0, 0, -3, 0, 3750),
            (3, 0, 122, 122, 3000),
            (6, 4, 0, 0, 1200),
            (2, 0, 1999, 175, 0),
        )
    )
    out = [
        messages.Hello(3, 100),
        messages.SetFriction(0b1011, (120, 0, 1000, 55)),
        messages.Loosen(0b1111),
        messages.SetAngle(0b0011, (2400, 3750, 0, 0)),
        messages.Stop(0b0100),
        messages.Query(),
        messages.Keepalive(),
        messages.HelloReply(3, 4, 3, 64, 2**32 - 1, b"\x00\xffSIM\x01\x02\x03", 0x0100),
        messages.Ack(255, 2),
        messages.Nak(7, 4, 6),
        messages.Status(123456, 9, 1, legs),
    ]
    return [(m, rng.randrange(256)) for m in out]


def test_crc_check_value_and_the_table_fallback_on_micropython():
    (out,) = run(
        "import wire, json\n"
        "data = bytes(range(256)) * 3\n"
        "print(json.dumps([wire.crc32(b'123456789'), wire.crc32(data), wire.crc32_table(data)]))\n"
    )
    data = bytes(range(256)) * 3
    assert out == [0xCBF43926, wire.crc32(data), wire.crc32(data)]


def test_every_message_encodes_to_the_same_bytes_on_both():
    rng = random.Random(1)
    sample = _sample_messages(rng)
    spec = [(int(messages.type_of(m)), seq, _jsonable(messages.fields_of(m))) for m, seq in sample]
    (out,) = run(
        "import wire, json, sys\n"
        "spec = json.loads(sys.stdin.read())\n"
        "def back(t, f):\n"
        "    if t == wire.HELLO_REPLY: return tuple(f[:5]) + (bytes(f[5]), f[6])\n"
        "    if t == wire.STATUS: return (f[0], f[1], f[2], tuple(tuple(r) for r in f[3]))\n"
        "    return tuple(tuple(x) if isinstance(x, list) else x for x in f)\n"
        "print(json.dumps([wire.encode_frame(t, s, wire.pack(t, back(t, f))).hex() for t, s, f in spec]))\n",
        stdin=json.dumps(spec),
    )
    assert out == [codec.encode(m, seq).hex() for m, seq in sample]


def test_a_damaged_stream_decodes_and_is_rejected_the_same_on_both():
    """Good frames of every type, garbage, bit flips, truncations and an oversize run, cut
    into random reads: MicroPython's decoder yields the same messages and the same counts."""
    rng = random.Random(7)
    stream = bytearray()
    for m, seq in _sample_messages(rng) * 4:
        frame = bytearray(codec.encode(m, seq))
        kind = rng.randrange(5)
        if kind == 1:
            frame[rng.randrange(len(frame) - 1)] ^= 1 << rng.randrange(8)
        elif kind == 2:
            frame = frame[: rng.randrange(1, len(frame) - 1)] + b"\x00"
        elif kind == 3:
            stream += bytes(rng.randrange(1, 256) for _ in range(rng.randrange(1, 30))) + b"\x00"
        stream += frame
    stream += b"\x01" * 300 + b"\x00" + codec.encode(messages.Query(), 3)
    cuts = sorted(rng.sample(range(1, len(stream)), 40))
    chunks = [bytes(stream[a:b]).hex() for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)]
    (out,) = run(
        "import wire, json, sys\n"
        "dec = wire.Decoder()\n"
        "got = []\n"
        "for chunk in json.loads(sys.stdin.read()):\n"
        "    for t, seq, f, raw in dec.feed(bytes.fromhex(chunk)):\n"
        "        got.append([t, seq, raw.hex()])\n"
        "print(json.dumps([got, dec.rejects.as_dict(), dec.accepted]))\n",
        stdin=json.dumps(chunks),
    )
    dec = wire.Decoder()
    got = [[t, seq, raw.hex()] for c in chunks for t, seq, _f, raw in dec.feed(bytes.fromhex(c))]
    assert out == [got, dec.rejects.as_dict(), dec.accepted]
    assert dec.accepted > 20 and dec.rejects.total() > 10 and dec.rejects.oversize == 1


def _jsonable(fields):
    if isinstance(fields, bytes):
        return list(fields)
    if isinstance(fields, tuple | list):
        return [_jsonable(f) for f in fields]
    return int(fields)
