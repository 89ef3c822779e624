"""The messages of leg-board protocol version 2 and their payload layouts.

One dataclass per message type; :func:`pack` and :func:`unpack` convert between them and
payload bytes. ``unpack`` checks every field's range, because after the CRC the field checks
are what stands between a rare undetected line error and a wrong command.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

PROTOCOL_VERSION = 2  # 2: CRC-32 frames (1 used CRC-16)
N_LEGS = 4
MAX_TARGET_MA = 1000
MAX_ANGLE_CDEG = 3750  # 37.5°, the leg fully extended
MAX_CURRENT_MA = 2000  # current sensor range, either sign
ALL_LEGS_MASK = (1 << N_LEGS) - 1


class LegState(IntEnum):
    LOOSE = 0
    LOOSENING = 1
    TIGHTENING = 2
    HOLDING = 3
    STOPPED = 4
    POSITIONING = 5
    FAULT = 6


class FaultCode(IntEnum):
    NONE = 0
    OVERCURRENT = 1
    STUCK = 2
    TIMEOUT = 3


FAULT_TEXT = {
    FaultCode.NONE: "no fault",
    FaultCode.OVERCURRENT: "over-current: motor current above the limit, motor switched off",
    FaultCode.STUCK: "stuck: the drive stalled where the nut had to move",
    FaultCode.TIMEOUT: "timeout: the motion did not finish within the board's limit",
}


class NakCode(IntEnum):
    BAD_VERSION = 1
    BAD_VALUE = 2
    UNSUPPORTED = 3
    NO_HELLO = 4
    FAULTED = 5


NAK_TEXT = {
    NakCode.BAD_VERSION: "protocol version not supported",
    NakCode.BAD_VALUE: "a value is out of range",
    NakCode.UNSUPPORTED: "the board does not support this command",
    NakCode.NO_HELLO: "command before HELLO",
    NakCode.FAULTED: "the leg is faulted; loosen it first",
}


class Capability(IntEnum):
    ANGLE_STOP = 1
    SIMULATED = 2


STATUS_FLAG_SIMULATED = 1
_CAPABILITY_MASK = Capability.ANGLE_STOP | Capability.SIMULATED


class MsgType(IntEnum):
    HELLO = 0x01
    SET_FRICTION = 0x02
    LOOSEN = 0x03
    SET_ANGLE = 0x04
    STOP = 0x05
    QUERY = 0x06
    HELLO_REPLY = 0x81
    ACK = 0x82
    NAK = 0x83
    STATUS = 0x84


class BadPayloadError(ValueError):
    """A payload of the right length whose fields are out of range."""


def legs_in(mask: int) -> tuple[int, ...]:
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


@dataclass(frozen=True)
class Hello:
    version: int = PROTOCOL_VERSION
    status_period_ms: int = 0


@dataclass(frozen=True)
class SetFriction:
    mask: int
    target_ma: tuple[int, int, int, int]


@dataclass(frozen=True)
class Loosen:
    mask: int


@dataclass(frozen=True)
class SetAngle:
    mask: int
    angle_cdeg: tuple[int, int, int, int]


@dataclass(frozen=True)
class Stop:
    mask: int


@dataclass(frozen=True)
class Query:
    pass


@dataclass(frozen=True)
class HelloReply:
    version: int
    legs: int
    capabilities: int
    max_payload: int
    board_time_ms: int


@dataclass(frozen=True)
class Ack:
    cmd_seq: int
    cmd_type: int


@dataclass(frozen=True)
class Nak:
    cmd_seq: int
    cmd_type: int
    code: int


@dataclass(frozen=True)
class LegReport:
    """One leg's part of a STATUS message, in wire units."""

    state: LegState
    fault: FaultCode
    current_ma: int
    target_ma: int
    angle_cdeg: int


@dataclass(frozen=True)
class Status:
    board_time_ms: int
    last_cmd_seq: int
    flags: int
    legs: tuple[LegReport, ...]


Message = Hello | SetFriction | Loosen | SetAngle | Stop | Query | HelloReply | Ack | Nak | Status

_LEG = struct.Struct("<BBhHH")
_STATUS_HEAD = struct.Struct("<IBB")
_FOUR = struct.Struct("<B4H")
_HELLO = struct.Struct("<BH")
_HELLO_REPLY = struct.Struct("<BBBBI")

PAYLOAD_LENGTH = {
    MsgType.HELLO: _HELLO.size,
    MsgType.SET_FRICTION: _FOUR.size,
    MsgType.LOOSEN: 1,
    MsgType.SET_ANGLE: _FOUR.size,
    MsgType.STOP: 1,
    MsgType.QUERY: 0,
    MsgType.HELLO_REPLY: _HELLO_REPLY.size,
    MsgType.ACK: 2,
    MsgType.NAK: 3,
    MsgType.STATUS: _STATUS_HEAD.size + N_LEGS * _LEG.size,
}

_TYPE_OF = {
    Hello: MsgType.HELLO,
    SetFriction: MsgType.SET_FRICTION,
    Loosen: MsgType.LOOSEN,
    SetAngle: MsgType.SET_ANGLE,
    Stop: MsgType.STOP,
    Query: MsgType.QUERY,
    HelloReply: MsgType.HELLO_REPLY,
    Ack: MsgType.ACK,
    Nak: MsgType.NAK,
    Status: MsgType.STATUS,
}


def type_of(msg: Message) -> MsgType:
    return _TYPE_OF[type(msg)]


def pack(msg: Message) -> bytes:
    """Payload bytes of a message (fields must already be in range)."""
    if isinstance(msg, Hello):
        return _HELLO.pack(msg.version, msg.status_period_ms)
    if isinstance(msg, SetFriction):
        return _FOUR.pack(msg.mask, *msg.target_ma)
    if isinstance(msg, SetAngle):
        return _FOUR.pack(msg.mask, *msg.angle_cdeg)
    if isinstance(msg, Loosen | Stop):
        return bytes((msg.mask,))
    if isinstance(msg, Query):
        return b""
    if isinstance(msg, HelloReply):
        return _HELLO_REPLY.pack(msg.version, msg.legs, msg.capabilities, msg.max_payload, msg.board_time_ms)
    if isinstance(msg, Ack):
        return bytes((msg.cmd_seq, msg.cmd_type))
    if isinstance(msg, Nak):
        return bytes((msg.cmd_seq, msg.cmd_type, msg.code))
    if isinstance(msg, Status):
        head = _STATUS_HEAD.pack(msg.board_time_ms, msg.last_cmd_seq, msg.flags)
        return head + b"".join(
            _LEG.pack(r.state, r.fault, r.current_ma, r.target_ma, r.angle_cdeg) for r in msg.legs
        )
    raise TypeError(f"not a leg-board message: {msg!r}")


def unpack(msg_type: int, payload: bytes) -> Message:
    """Interpret a payload of known type and length; :class:`BadPayloadError` if out of range."""
    t = MsgType(msg_type)
    if t is MsgType.HELLO:
        version, period = _HELLO.unpack(payload)
        if version == 0:
            raise BadPayloadError("version 0")
        return Hello(version, period)
    if t in (MsgType.SET_FRICTION, MsgType.SET_ANGLE):
        mask, *values = _FOUR.unpack(payload)
        _check_mask(mask)
        limit = MAX_TARGET_MA if t is MsgType.SET_FRICTION else MAX_ANGLE_CDEG
        if any(v > limit for v in values):
            raise BadPayloadError(f"value above {limit}")
        cls = SetFriction if t is MsgType.SET_FRICTION else SetAngle
        return cls(mask, tuple(values))
    if t in (MsgType.LOOSEN, MsgType.STOP):
        _check_mask(payload[0])
        return (Loosen if t is MsgType.LOOSEN else Stop)(payload[0])
    if t is MsgType.QUERY:
        return Query()
    if t is MsgType.HELLO_REPLY:
        version, legs, caps, max_payload, clock = _HELLO_REPLY.unpack(payload)
        if version == 0 or legs != N_LEGS or caps & ~_CAPABILITY_MASK or max_payload == 0:
            raise BadPayloadError("hello reply fields")
        return HelloReply(version, legs, caps, max_payload, clock)
    if t is MsgType.ACK:
        return Ack(payload[0], _command_type(payload[1]))
    if t is MsgType.NAK:
        if payload[2] not in NakCode._value2member_map_:
            raise BadPayloadError(f"NAK code {payload[2]}")
        return Nak(payload[0], _command_type(payload[1]), payload[2])
    clock, last_seq, flags = _STATUS_HEAD.unpack_from(payload)
    if flags & ~STATUS_FLAG_SIMULATED:
        raise BadPayloadError(f"status flags 0x{flags:02x}")
    legs = []
    for i in range(N_LEGS):
        state, fault, current, target, angle = _LEG.unpack_from(payload, _STATUS_HEAD.size + i * _LEG.size)
        if state > LegState.FAULT or fault > FaultCode.TIMEOUT:
            raise BadPayloadError(f"leg {i} state {state} fault {fault}")
        if target > MAX_TARGET_MA or angle > MAX_ANGLE_CDEG or abs(current) > MAX_CURRENT_MA:
            raise BadPayloadError(f"leg {i} target {target} angle {angle}")
        if (fault != FaultCode.NONE) != (state == LegState.FAULT):
            raise BadPayloadError(f"leg {i} fault {fault} in state {state}")
        legs.append(LegReport(LegState(state), FaultCode(fault), current, target, angle))
    return Status(clock, last_seq, flags, tuple(legs))


def _command_type(value: int) -> int:
    if value not in MsgType._value2member_map_ or value >= 0x80:
        raise BadPayloadError(f"command type 0x{value:02x}")
    return value
