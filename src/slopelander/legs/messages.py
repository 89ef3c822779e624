"""The messages of leg-board protocol version 3 as typed objects, for the companion's driver.

The numbers, layouts and range checks are :mod:`slopelander.legs.wire`'s, the module the
board's firmware shares; this layer gives each message a frozen dataclass and each code an
enum. :func:`pack` and :func:`unpack` go through ``wire`` and nothing else, so the driver and
the firmware cannot disagree about a byte.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from slopelander.legs import wire
from slopelander.legs.wire import (
    ALL_LEGS_MASK,
    BOARD_ID_LEN,
    MAX_ANGLE_CDEG,
    MAX_CURRENT_MA,
    MAX_TARGET_MA,
    N_LEGS,
    PROTOCOL_VERSION,
    STATUS_FLAG_SIMULATED,
    legs_in,
    mask_of,
)

BadPayloadError = wire.BadPayloadError


class LegState(IntEnum):
    LOOSE = wire.LOOSE
    LOOSENING = wire.LOOSENING
    TIGHTENING = wire.TIGHTENING
    HOLDING = wire.HOLDING
    STOPPED = wire.STOPPED
    POSITIONING = wire.POSITIONING
    FAULT = wire.FAULT


class FaultCode(IntEnum):
    NONE = wire.FAULT_NONE
    OVERCURRENT = wire.FAULT_OVERCURRENT
    STUCK = wire.FAULT_STUCK
    TIMEOUT = wire.FAULT_TIMEOUT
    SENSE = wire.FAULT_SENSE
    TRAVEL = wire.FAULT_TRAVEL


FAULT_TEXT = {
    FaultCode.NONE: "no fault",
    FaultCode.OVERCURRENT: "over-current: motor current above the limit, motor switched off",
    FaultCode.STUCK: "stuck: the drive stalled where the nut had to move",
    FaultCode.TIMEOUT: "timeout: the motion did not finish within the board's limit",
    FaultCode.SENSE: "no current while driven: current sense or motor wiring open, motor switched off",
    FaultCode.TRAVEL: "end of travel: the nut ran past its range (a slipping gear?), motor switched off",
}


class NakCode(IntEnum):
    BAD_VERSION = wire.NAK_BAD_VERSION
    BAD_VALUE = wire.NAK_BAD_VALUE
    UNSUPPORTED = wire.NAK_UNSUPPORTED
    NO_HELLO = wire.NAK_NO_HELLO
    FAULTED = wire.NAK_FAULTED
    ABOVE_LIMIT = wire.NAK_ABOVE_LIMIT


NAK_TEXT = {
    NakCode.BAD_VERSION: "protocol version not supported",
    NakCode.BAD_VALUE: "a value is out of range",
    NakCode.UNSUPPORTED: "the board does not support this command",
    NakCode.NO_HELLO: "command before HELLO",
    NakCode.FAULTED: "the leg is faulted; loosen it first",
    NakCode.ABOVE_LIMIT: "current target above the board's configured limit",
}


class Capability(IntEnum):
    ANGLE_STOP = wire.CAP_ANGLE_STOP
    SIMULATED = wire.CAP_SIMULATED


class MsgType(IntEnum):
    HELLO = wire.HELLO
    SET_FRICTION = wire.SET_FRICTION
    LOOSEN = wire.LOOSEN
    SET_ANGLE = wire.SET_ANGLE
    STOP = wire.STOP
    QUERY = wire.QUERY
    KEEPALIVE = wire.KEEPALIVE
    HELLO_REPLY = wire.HELLO_REPLY
    ACK = wire.ACK
    NAK = wire.NAK
    STATUS = wire.STATUS


PAYLOAD_LENGTH = {MsgType(t): n for t, n in wire.PAYLOAD_LENGTH.items()}


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
class Keepalive:
    """The companion is alive (no reply); sent when it has sent nothing else for a while."""


@dataclass(frozen=True)
class HelloReply:
    version: int
    legs: int
    capabilities: int
    max_payload: int
    board_time_ms: int
    board_id: bytes = bytes(BOARD_ID_LEN)
    firmware: int = 0

    @property
    def board_id_hex(self) -> str:
        return self.board_id.hex()

    @property
    def firmware_text(self) -> str:
        return f"{self.firmware >> 8}.{self.firmware & 0xFF}"


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


Message = Hello | SetFriction | Loosen | SetAngle | Stop | Query | Keepalive | HelloReply | Ack | Nak | Status

_TYPE_OF = {
    Hello: MsgType.HELLO,
    SetFriction: MsgType.SET_FRICTION,
    Loosen: MsgType.LOOSEN,
    SetAngle: MsgType.SET_ANGLE,
    Stop: MsgType.STOP,
    Query: MsgType.QUERY,
    Keepalive: MsgType.KEEPALIVE,
    HelloReply: MsgType.HELLO_REPLY,
    Ack: MsgType.ACK,
    Nak: MsgType.NAK,
    Status: MsgType.STATUS,
}


def type_of(msg: Message) -> MsgType:
    return _TYPE_OF[type(msg)]


def fields_of(msg: Message) -> tuple:
    """The message as ``wire``'s field tuple."""
    if isinstance(msg, Hello):
        return (msg.version, msg.status_period_ms)
    if isinstance(msg, SetFriction):
        return (msg.mask, tuple(msg.target_ma))
    if isinstance(msg, SetAngle):
        return (msg.mask, tuple(msg.angle_cdeg))
    if isinstance(msg, Loosen | Stop):
        return (msg.mask,)
    if isinstance(msg, Query | Keepalive):
        return ()
    if isinstance(msg, HelloReply):
        return (
            msg.version,
            msg.legs,
            msg.capabilities,
            msg.max_payload,
            msg.board_time_ms,
            msg.board_id,
            msg.firmware,
        )
    if isinstance(msg, Ack):
        return (msg.cmd_seq, msg.cmd_type)
    if isinstance(msg, Nak):
        return (msg.cmd_seq, msg.cmd_type, msg.code)
    if isinstance(msg, Status):
        legs = tuple((r.state, r.fault, r.current_ma, r.target_ma, r.angle_cdeg) for r in msg.legs)
        return (msg.board_time_ms, msg.last_cmd_seq, msg.flags, legs)
    raise TypeError(f"not a leg-board message: {msg!r}")


def pack(msg: Message) -> bytes:
    """Payload bytes of a message (fields must already be in range)."""
    return wire.pack(type_of(msg), fields_of(msg))


def from_fields(msg_type: int, f: tuple) -> Message:
    """The typed message of a field tuple ``wire.unpack`` returned."""
    t = MsgType(msg_type)
    if t is MsgType.HELLO:
        return Hello(*f)
    if t is MsgType.SET_FRICTION:
        return SetFriction(f[0], tuple(f[1]))
    if t is MsgType.SET_ANGLE:
        return SetAngle(f[0], tuple(f[1]))
    if t is MsgType.LOOSEN:
        return Loosen(f[0])
    if t is MsgType.STOP:
        return Stop(f[0])
    if t is MsgType.QUERY:
        return Query()
    if t is MsgType.KEEPALIVE:
        return Keepalive()
    if t is MsgType.HELLO_REPLY:
        return HelloReply(*f)
    if t is MsgType.ACK:
        return Ack(*f)
    if t is MsgType.NAK:
        return Nak(*f)
    legs = tuple(LegReport(LegState(s), FaultCode(fault), c, tg, a) for s, fault, c, tg, a in f[3])
    return Status(f[0], f[1], f[2], legs)


def unpack(msg_type: int, payload: bytes) -> Message:
    """Interpret a payload of known type and length; :class:`BadPayloadError` if out of range."""
    return from_fields(msg_type, wire.unpack(msg_type, payload))


__all__ = [
    "ALL_LEGS_MASK",
    "BOARD_ID_LEN",
    "MAX_ANGLE_CDEG",
    "MAX_CURRENT_MA",
    "MAX_TARGET_MA",
    "N_LEGS",
    "PROTOCOL_VERSION",
    "STATUS_FLAG_SIMULATED",
    "BadPayloadError",
    "legs_in",
    "mask_of",
]
