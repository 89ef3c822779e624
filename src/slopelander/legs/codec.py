"""The leg-board codec on the companion's side: typed messages to bytes and back.

``encode(msg, seq)`` gives the bytes to write (delimiter included); a :class:`Decoder` is fed
whatever the port returns and yields :class:`Frame` objects. Framing, CRC, payload layouts and
the order of the checks are :mod:`slopelander.legs.wire`'s, shared with the board's firmware;
every dropped frame increments a counter in :attr:`Decoder.rejects`.
"""

from __future__ import annotations

from dataclasses import dataclass

from slopelander.legs import messages, wire
from slopelander.legs.messages import Message, MsgType
from slopelander.legs.wire import RejectCounters


def encode(msg: Message, seq: int) -> bytes:
    """Bytes to write for ``msg`` with sequence number ``seq`` (delimiter included)."""
    return wire.encode_frame(messages.type_of(msg), seq, messages.pack(msg))


@dataclass(frozen=True)
class Frame:
    """A decoded message with its sequence number and the raw frame it came from."""

    seq: int
    message: Message
    raw: bytes


class Decoder:
    """Streaming decoder: feed bytes, get :class:`Frame` objects, count rejects."""

    def __init__(self) -> None:
        self._wire = wire.Decoder()

    @property
    def rejects(self) -> RejectCounters:
        return self._wire.rejects

    @property
    def accepted(self) -> int:
        return self._wire.accepted

    @property
    def foreign_version(self) -> int | None:
        """The protocol version of a board that answered HELLO in another version's layout."""
        return self._wire.foreign_version

    def feed(self, data: bytes) -> list[Frame]:
        return [
            Frame(seq, messages.from_fields(t, fields), raw) for t, seq, fields, raw in self._wire.feed(data)
        ]


__all__ = ["Decoder", "Frame", "MsgType", "encode"]
