"""The one codec the driver and the simulated board share: messages to bytes and back.

:class:`Decoder` is a byte stream in, messages out. It never raises on what the line
delivers; every dropped frame increments a counter in :attr:`Decoder.rejects`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from slopelander.legs import messages
from slopelander.legs.framing import FrameSplitter, RejectCounters, encode_frame
from slopelander.legs.messages import PAYLOAD_LENGTH, BadPayloadError, Message, MsgType


def encode(msg: Message, seq: int) -> bytes:
    """Bytes to write for ``msg`` with sequence number ``seq`` (delimiter included)."""
    return encode_frame(messages.type_of(msg), seq, messages.pack(msg))


@dataclass(frozen=True)
class Frame:
    """A decoded message with its sequence number and the raw frame it came from."""

    seq: int
    message: Message
    raw: bytes


@dataclass
class Decoder:
    """Streaming decoder: feed bytes, get :class:`Frame` objects, count rejects."""

    accepted: int = 0
    _splitter: FrameSplitter = field(default_factory=FrameSplitter)

    @property
    def rejects(self) -> RejectCounters:
        return self._splitter.rejects

    def feed(self, data: bytes) -> list[Frame]:
        out = []
        for raw in self._splitter.feed(data):
            expected = PAYLOAD_LENGTH.get(raw.msg_type)
            if expected is None:
                self.rejects.unknown_type += 1
                continue
            if len(raw.payload) != expected:
                self.rejects.payload_length += 1
                continue
            try:
                msg = messages.unpack(raw.msg_type, raw.payload)
            except BadPayloadError:
                self.rejects.bad_value += 1
                continue
            self.accepted += 1
            out.append(Frame(raw.seq, msg, raw.raw))
        return out


__all__ = ["Decoder", "Frame", "MsgType", "encode"]
