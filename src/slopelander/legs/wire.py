"""The leg-board protocol on the wire: numbers, framing, CRC and payload layouts.

This one module is shared, unchanged, by the companion's driver (CPython) and the leg-board
firmware (MicroPython, ``firmware/legboard``): it is copied to the board as ``wire.py`` and
imported there as ``wire``. It therefore stays inside what both interpreters accept: no
dataclasses, enums, typing or ``__future__`` imports, no bytearray slice deletion; plain
classes, tuples and ``struct``. The driver's typed messages (:mod:`slopelander.legs.messages`)
are a layer over it. ``docs/leg-protocol.md`` is the specification.

A frame on the line is ``COBS(type | seq | len | payload | crc32) 0x00`` (CRC-32 as zlib,
most significant byte first; payload fields little-endian).
"""

import struct

try:
    from binascii import crc32 as _crc32
except ImportError:  # a MicroPython build without binascii.crc32: the table below
    _crc32 = None

PROTOCOL_VERSION = 3  # 3: board id and firmware version in HELLO_REPLY, KEEPALIVE, faults SENSE, TRAVEL
N_LEGS = 4
ALL_LEGS_MASK = (1 << N_LEGS) - 1
MAX_TARGET_MA = 1000
MAX_ANGLE_CDEG = 3750  # 37.5°, the leg fully extended
MAX_CURRENT_MA = 2000  # reported current range, either sign
BOARD_ID_LEN = 8

MAX_PAYLOAD = 64
HEADER_LEN = 3
CRC_LEN = 4
MAX_RAW = HEADER_LEN + MAX_PAYLOAD + CRC_LEN
# COBS adds one byte per 254 data bytes; a raw frame never reaches 254 bytes.
MAX_ENCODED = MAX_RAW + 1
DELIMITER = b"\x00"

# message types: companion → board 0x01–0x3F, board → companion 0x80–0xBF
HELLO = 0x01
SET_FRICTION = 0x02
LOOSEN = 0x03
SET_ANGLE = 0x04
STOP = 0x05
QUERY = 0x06
KEEPALIVE = 0x07
HELLO_REPLY = 0x81
ACK = 0x82
NAK = 0x83
STATUS = 0x84
COMMAND_TYPES = (HELLO, SET_FRICTION, LOOSEN, SET_ANGLE, STOP, QUERY, KEEPALIVE)

# leg states
LOOSE = 0
LOOSENING = 1
TIGHTENING = 2
HOLDING = 3
STOPPED = 4
POSITIONING = 5
FAULT = 6

# fault codes
FAULT_NONE = 0
FAULT_OVERCURRENT = 1
FAULT_STUCK = 2
FAULT_TIMEOUT = 3
FAULT_SENSE = 4
FAULT_TRAVEL = 5
LAST_FAULT = FAULT_TRAVEL

# NAK codes
NAK_BAD_VERSION = 1
NAK_BAD_VALUE = 2
NAK_UNSUPPORTED = 3
NAK_NO_HELLO = 4
NAK_FAULTED = 5
NAK_ABOVE_LIMIT = 6
LAST_NAK = NAK_ABOVE_LIMIT

# capability bits (HELLO_REPLY) and STATUS flags
CAP_ANGLE_STOP = 1
CAP_SIMULATED = 2
CAPABILITY_MASK = CAP_ANGLE_STOP | CAP_SIMULATED
STATUS_FLAG_SIMULATED = 1

_HELLO = "<BH"
_FOUR = "<B4H"
_HELLO_REPLY = "<BBBBI8sH"
_STATUS_HEAD = "<IBB"
_LEG = "<BBhHH"
_STATUS_HEAD_LEN = struct.calcsize(_STATUS_HEAD)
_LEG_LEN = struct.calcsize(_LEG)

PAYLOAD_LENGTH = {
    HELLO: struct.calcsize(_HELLO),
    SET_FRICTION: struct.calcsize(_FOUR),
    LOOSEN: 1,
    SET_ANGLE: struct.calcsize(_FOUR),
    STOP: 1,
    QUERY: 0,
    KEEPALIVE: 0,
    HELLO_REPLY: struct.calcsize(_HELLO_REPLY),
    ACK: 2,
    NAK: 3,
    STATUS: _STATUS_HEAD_LEN + N_LEGS * _LEG_LEN,
}


# ---- CRC-32 and COBS ------------------------------------------------------------------
_TABLE = None


def crc32_table(data) -> int:
    """CRC-32 (IEEE 802.3, reflected 0xEDB88320) by table, for builds without binascii.crc32."""
    global _TABLE
    if _TABLE is None:
        table = []
        for n in range(256):
            c = n
            for _ in range(8):
                c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
            table.append(c)
        _TABLE = table
    c = 0xFFFFFFFF
    for b in data:
        c = _TABLE[(c ^ b) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF


def crc32(data) -> int:
    """CRC-32 as zlib (check value 0xCBF43926): a 16-bit CRC let a corrupted frame through in a
    10^6-frame mutation run (docs/leg-protocol.md)."""
    if _crc32 is None:
        return crc32_table(data)
    return _crc32(data) & 0xFFFFFFFF


def cobs_encode(raw) -> bytes:
    """COBS-encode ``raw`` (shorter than 254 bytes, so no 0xFF blocks are needed)."""
    return b"".join(bytes((len(block) + 1,)) + block for block in bytes(raw).split(b"\x00"))


def cobs_decode(enc):
    """Decode one COBS block sequence without its delimiter; ``None`` if malformed."""
    out = bytearray()
    n = len(enc)
    i = 0
    while i < n:
        code = enc[i]
        end = i + code
        if code == 0 or end > n:
            return None
        out += enc[i + 1 : end]
        i = end
        if i < n:
            out.append(0)
    return bytes(out)


def pack_frame(msg_type: int, seq: int, payload) -> bytes:
    """The raw frame (before COBS) for one message."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    body = bytes((msg_type & 0xFF, seq & 0xFF, len(payload))) + bytes(payload)
    return body + crc32(body).to_bytes(CRC_LEN, "big")


def encode_frame(msg_type: int, seq: int, payload) -> bytes:
    """Bytes to write on the line for one message, delimiter included."""
    return cobs_encode(pack_frame(msg_type, seq, payload)) + DELIMITER


# ---- payloads -------------------------------------------------------------------------
class BadPayloadError(ValueError):
    """A payload of the right length whose fields are out of range."""


def legs_in(mask: int) -> tuple:
    """Leg indices selected by a leg mask."""
    return tuple(i for i in range(N_LEGS) if mask >> i & 1)


def mask_of(legs) -> int:
    mask = 0
    for leg in legs:
        mask |= 1 << leg
    return mask


def _check_mask(mask: int) -> None:
    if mask == 0 or mask & ~ALL_LEGS_MASK:
        raise BadPayloadError(f"leg mask 0x{mask:02x}")


def pack(msg_type: int, fields: tuple) -> bytes:
    """Payload bytes of one message from its field tuple (see :func:`unpack` for the layouts);
    the fields must already be in range."""
    if msg_type == HELLO:
        return struct.pack(_HELLO, fields[0], fields[1])
    if msg_type in (SET_FRICTION, SET_ANGLE):
        v = fields[1]
        return struct.pack(_FOUR, fields[0], v[0], v[1], v[2], v[3])
    if msg_type in (LOOSEN, STOP):
        return bytes((fields[0],))
    if msg_type in (QUERY, KEEPALIVE):
        return b""
    if msg_type == HELLO_REPLY:
        version, legs, caps, max_payload, clock, board_id, firmware = fields
        return struct.pack(_HELLO_REPLY, version, legs, caps, max_payload, clock, board_id, firmware)
    if msg_type == ACK:
        return bytes((fields[0], fields[1]))
    if msg_type == NAK:
        return bytes((fields[0], fields[1], fields[2]))
    if msg_type == STATUS:
        out = struct.pack(_STATUS_HEAD, fields[0], fields[1], fields[2])
        for r in fields[3]:
            out += struct.pack(_LEG, r[0], r[1], r[2], r[3], r[4])
        return out
    raise ValueError(f"not a leg-board message type: 0x{msg_type:02x}")


def unpack(msg_type: int, payload) -> tuple:
    """The field tuple of a payload of known type and length; :class:`BadPayloadError` if a field
    is out of range. Layouts:

    - HELLO ``(version, status_period_ms)``; SET_FRICTION, SET_ANGLE ``(mask, (v0, v1, v2, v3))``;
      LOOSEN, STOP ``(mask,)``; QUERY, KEEPALIVE ``()``;
    - HELLO_REPLY ``(version, legs, capabilities, max_payload, board_time_ms, board_id, firmware)``,
      or ``(version,)`` from a board of another protocol version (see :func:`foreign_version`);
    - ACK ``(cmd_seq, cmd_type)``; NAK ``(cmd_seq, cmd_type, code)``;
    - STATUS ``(board_time_ms, last_cmd_seq, flags, legs)`` with four
      ``(state, fault, current_ma, target_ma, angle_cdeg)``.
    """
    if msg_type == HELLO:
        version, period = struct.unpack(_HELLO, payload)
        if version == 0:
            raise BadPayloadError("version 0")
        return (version, period)
    if msg_type in (SET_FRICTION, SET_ANGLE):
        values = struct.unpack(_FOUR, payload)
        _check_mask(values[0])
        limit = MAX_TARGET_MA if msg_type == SET_FRICTION else MAX_ANGLE_CDEG
        for v in values[1:]:
            if v > limit:
                raise BadPayloadError(f"value {v} above {limit}")
        return (values[0], values[1:])
    if msg_type in (LOOSEN, STOP):
        _check_mask(payload[0])
        return (payload[0],)
    if msg_type in (QUERY, KEEPALIVE):
        return ()
    if msg_type == HELLO_REPLY:
        version, legs, caps, max_payload, clock, board_id, firmware = struct.unpack(_HELLO_REPLY, payload)
        # any leg count decodes, so that the driver can refuse a board with another count by name
        if version == 0 or legs == 0 or caps & ~CAPABILITY_MASK or max_payload == 0:
            raise BadPayloadError("hello reply fields")
        return (version, legs, caps, max_payload, clock, bytes(board_id), firmware)
    if msg_type == ACK:
        return (payload[0], _command_type(payload[1]))
    if msg_type == NAK:
        if not 1 <= payload[2] <= LAST_NAK:
            raise BadPayloadError(f"NAK code {payload[2]}")
        return (payload[0], _command_type(payload[1]), payload[2])
    if msg_type == STATUS:
        clock, last_seq, flags = struct.unpack_from(_STATUS_HEAD, payload, 0)
        if flags & ~STATUS_FLAG_SIMULATED:
            raise BadPayloadError(f"status flags 0x{flags:02x}")
        legs = []
        for i in range(N_LEGS):
            r = struct.unpack_from(_LEG, payload, _STATUS_HEAD_LEN + i * _LEG_LEN)
            state, fault, current, target, angle = r
            if state > FAULT or fault > LAST_FAULT:
                raise BadPayloadError(f"leg {i} state {state} fault {fault}")
            if target > MAX_TARGET_MA or angle > MAX_ANGLE_CDEG or abs(current) > MAX_CURRENT_MA:
                raise BadPayloadError(f"leg {i} target {target} angle {angle}")
            if (fault != FAULT_NONE) != (state == FAULT):
                raise BadPayloadError(f"leg {i} fault {fault} in state {state}")
            legs.append(r)
        return (clock, last_seq, flags, tuple(legs))
    raise BadPayloadError(f"type 0x{msg_type:02x}")


def foreign_version(msg_type: int, payload):
    """The version byte of a HELLO_REPLY from a board of another protocol version, else None.

    Every version's HELLO_REPLY starts with the version, whatever follows, so a driver can say
    which version the board speaks instead of counting its reply as garbage."""
    if msg_type == HELLO_REPLY and len(payload) >= 1 and payload[0] not in (0, PROTOCOL_VERSION):
        return payload[0]
    return None


def _command_type(value: int) -> int:
    if value not in COMMAND_TYPES:
        raise BadPayloadError(f"command type 0x{value:02x}")
    return value


# ---- streams --------------------------------------------------------------------------
REJECT_NAMES = (
    "oversize",
    "cobs",
    "truncated",
    "length",
    "crc",
    "unknown_type",
    "payload_length",
    "bad_value",
)


class RejectCounters:
    """How many frames were dropped, by the first check each one failed."""

    def __init__(self) -> None:
        self.oversize = 0
        self.cobs = 0
        self.truncated = 0
        self.length = 0
        self.crc = 0
        self.unknown_type = 0
        self.payload_length = 0
        self.bad_value = 0

    def total(self) -> int:
        return (
            self.oversize
            + self.cobs
            + self.truncated
            + self.length
            + self.crc
            + self.unknown_type
            + self.payload_length
            + self.bad_value
        )

    def as_dict(self) -> dict:
        return {name: getattr(self, name) for name in REJECT_NAMES}

    def __repr__(self) -> str:
        return "RejectCounters(" + ", ".join(f"{k}={v}" for k, v in self.as_dict().items()) + ")"


class RawFrame:
    """A frame whose framing and CRC are good; its payload is not yet interpreted."""

    def __init__(self, msg_type: int, seq: int, payload: bytes, raw: bytes) -> None:
        self.msg_type = msg_type
        self.seq = seq
        self.payload = payload
        self.raw = raw

    def __eq__(self, other: object) -> bool:
        return isinstance(other, RawFrame) and self.raw == other.raw

    def __repr__(self) -> str:
        return f"RawFrame(type=0x{self.msg_type:02x}, seq={self.seq}, payload={self.payload!r})"


class FrameSplitter:
    """Streaming framing layer: bytes in, CRC-checked raw frames out; never raises."""

    def __init__(self) -> None:
        self.rejects = RejectCounters()
        self._buf = bytearray()
        self._discarding = False

    def feed(self, data) -> list:
        frames = []
        pieces = bytes(data).split(DELIMITER)
        last = len(pieces) - 1
        for i, piece in enumerate(pieces):  # every piece but the last is followed by a delimiter
            self._append(piece)
            if i < last:
                self._end_frame(frames)
        return frames

    def _append(self, piece: bytes) -> None:
        if self._discarding or not piece:
            return
        if len(self._buf) + len(piece) > MAX_ENCODED:
            self.rejects.oversize += 1
            self._buf = bytearray()
            self._discarding = True
            return
        self._buf += piece

    def _end_frame(self, frames: list) -> None:
        if self._discarding:
            self._discarding = False
            return
        if not self._buf:
            return  # empty frame: a spare delimiter
        enc = bytes(self._buf)
        self._buf = bytearray()
        frame = self.check(enc)
        if frame is not None:
            frames.append(frame)

    def check(self, enc: bytes):
        """Decode and check one encoded frame (no delimiter), counting a reject."""
        raw = cobs_decode(enc)
        if raw is None:
            self.rejects.cobs += 1
            return None
        n = len(raw)
        if n < HEADER_LEN + CRC_LEN or n < HEADER_LEN + raw[2] + CRC_LEN:
            self.rejects.truncated += 1
            return None
        if n > HEADER_LEN + raw[2] + CRC_LEN:
            self.rejects.length += 1
            return None
        if crc32(raw[:-CRC_LEN]) != int.from_bytes(raw[-CRC_LEN:], "big"):
            self.rejects.crc += 1
            return None
        return RawFrame(raw[0], raw[1], raw[HEADER_LEN:-CRC_LEN], raw)


class Decoder:
    """Streaming decoder: bytes in, ``(msg_type, seq, fields, raw)`` tuples out, rejects counted.

    After the CRC, a frame must have a known type, that type's exact payload length and fields
    in range; :attr:`foreign_version` keeps the version of a HELLO_REPLY from a board of another
    protocol version (the frame itself is counted as ``payload_length``)."""

    def __init__(self) -> None:
        self.splitter = FrameSplitter()
        self.rejects = self.splitter.rejects
        self.accepted = 0
        self.foreign_version = None

    def feed(self, data) -> list:
        out = []
        for raw in self.splitter.feed(data):
            expected = PAYLOAD_LENGTH.get(raw.msg_type)
            if expected is None:
                self.rejects.unknown_type += 1
                continue
            if len(raw.payload) != expected:
                foreign = foreign_version(raw.msg_type, raw.payload)
                if foreign is not None:
                    self.foreign_version = foreign
                self.rejects.payload_length += 1
                continue
            try:
                fields = unpack(raw.msg_type, raw.payload)
            except BadPayloadError:
                foreign = foreign_version(raw.msg_type, raw.payload)
                if foreign is not None:
                    self.foreign_version = foreign
                self.rejects.bad_value += 1
                continue
            self.accepted += 1
            out.append((raw.msg_type, raw.seq, fields, raw.raw))
        return out
