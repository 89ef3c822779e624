"""Frames on the serial line: COBS with a 0x00 delimiter and CRC-32 (IEEE 802.3).

The framing itself lives in :mod:`slopelander.legs.wire`, the module the board's firmware
shares; this module names its parts for the companion's side. See ``docs/leg-protocol.md`` §2.
"""

from __future__ import annotations

from slopelander.legs.wire import (
    CRC_LEN,
    DELIMITER,
    HEADER_LEN,
    MAX_ENCODED,
    MAX_PAYLOAD,
    MAX_RAW,
    FrameSplitter,
    RawFrame,
    RejectCounters,
    cobs_decode,
    cobs_encode,
    crc32,
    encode_frame,
    pack_frame,
)

__all__ = [
    "CRC_LEN",
    "DELIMITER",
    "HEADER_LEN",
    "MAX_ENCODED",
    "MAX_PAYLOAD",
    "MAX_RAW",
    "FrameSplitter",
    "RawFrame",
    "RejectCounters",
    "cobs_decode",
    "cobs_encode",
    "crc32",
    "encode_frame",
    "pack_frame",
]
