"""Drop unwanted MAVLink frames by message id before pymavlink decodes them.

Decoding a message in Python (unpacking, a message object) is most of the companion's CPU at the
full IMU rate, and an autopilot streams more than a landing reads (its serial ports' stream
rates, a second IMU message, telemetry for the ground station). The message id sits in the frame
header: MAVLink 2 (``0xFD``) bytes 7..9, little-endian; MAVLink 1 (``0xFE``) byte 5.

A frame is only a frame when its CRC checks (pymavlink's own CRC-16/MCRF4XX, ``x25crc``, with the
message's CRC_EXTRA from the dialect): a magic byte in line noise, or a corrupt length byte, is
then one byte of noise and the search resumes at the next magic byte, so one bad byte on a serial
line never swallows the good frames after it (the length byte alone used to be trusted). MAVLink's
C parser does the same (``mavlink_helpers.h``, ``mavlink_frame_char_buffer``: a bad CRC restarts
the search at the next start byte). Noise is counted and dropped; the decoder only ever sees whole,
checked frames. A signed frame's signature is checked by pymavlink when the frame is kept.

Frame lengths: MAVLink 2 is 10 header + payload + 2 CRC, + 13 when the signed flag (incompat bit 0)
is set; MAVLink 1 is 6 header + payload + 2 CRC. A frame cut at the end of a read is held until the
rest arrives, unless a complete checked frame starts inside it (then the held start was noise).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping

from pymavlink.dialects.v20 import ardupilotmega as _dialect
from pymavlink.generator import mavcrc

STX_V2 = 0xFD
STX_V1 = 0xFE
_HEADER_V2, _HEADER_V1 = 10, 6
_SIGNATURE = 13
_CRC = 2
_IFLAG_SIGNED = 0x01
#: the CRC_EXTRA byte of every message the dialect knows (the last byte the CRC takes in)
CRC_EXTRA: dict[int, int] = {msgid: cls.crc_extra for msgid, cls in _dialect.mavlink_map.items()}
_MAGIC = re.compile(b"[\xfd\xfe]")


def _crc(data: bytes, extra: int) -> int:
    """The MAVLink CRC of ``data`` then ``extra``: pymavlink's own (its C ``fastcrc`` binding when
    installed, as pymavlink uses it, else its pure-Python ``x25crc_slow``)."""
    fast = mavcrc.mcrf4xx
    if fast is not None:
        return fast(bytes((extra,)), fast(data, 0xFFFF))
    crc = mavcrc.x25crc_slow(data)
    crc.accumulate(bytes((extra,)))
    return crc.crc


class FrameFilter:
    """Feed raw link bytes; get back only the checked frames whose message id is in ``keep``."""

    def __init__(self, keep: Iterable[int], crc_extra: Mapping[int, int] = CRC_EXTRA) -> None:
        self.keep = frozenset(int(k) for k in keep)
        if not self.keep:
            raise ValueError("a frame filter that keeps no message id would silence the link")
        self.crc_extra = crc_extra
        self._held = b""
        #: frames skipped and frames passed since start (for the benchmark and the tests)
        self.dropped = 0
        self.passed = 0
        #: bytes that were not part of a checked frame (line noise, corrupt frames)
        self.noise = 0

    def _frame_at(self, buf: bytes, i: int, n: int) -> tuple[int, int] | bool | None:
        """(size, msgid) of a checked frame at ``i``; None: it is not one; False: cut short."""
        if buf[i] == STX_V2:
            if n - i < _HEADER_V2:
                return False
            incompat = buf[i + 2]
            if incompat & ~_IFLAG_SIGNED:  # an incompatibility flag nobody defined: not a frame
                return None
            body = _HEADER_V2 + buf[i + 1]
            size = body + _CRC + (_SIGNATURE if incompat & _IFLAG_SIGNED else 0)
            msgid = buf[i + 7] | buf[i + 8] << 8 | buf[i + 9] << 16
        else:
            if n - i < _HEADER_V1:
                return False
            body = _HEADER_V1 + buf[i + 1]
            size = body + _CRC
            msgid = buf[i + 5]
        extra = self.crc_extra.get(msgid)
        if extra is None:  # unknown to the dialect: the decoder could not read it either
            return None
        if n - i < body + _CRC:
            return False
        if _crc(buf[i + 1 : i + body], extra) != (buf[i + body] | buf[i + body + 1] << 8):
            return None
        if n - i < size:
            return False
        return size, msgid

    def _checked_frame_after(self, buf: bytes, i: int, n: int) -> bool:
        """Whether a complete checked frame starts after ``i``: then what starts at ``i`` is noise."""
        m = _MAGIC.search(buf, i + 1)
        while m is not None:
            if self._frame_at(buf, m.start(), n):
                return True
            m = _MAGIC.search(buf, m.start() + 1)
        return False

    def feed(self, data: bytes) -> bytes:
        """The kept frames of ``held + data``; an incomplete last frame is held for the next call."""
        buf = self._held + data if self._held else bytes(data)
        out: list[bytes] = []
        i, n = 0, len(buf)
        keep = self.keep
        while i < n:
            b = buf[i]
            if b != STX_V2 and b != STX_V1:  # noise up to the next magic byte
                m = _MAGIC.search(buf, i + 1)
                j = n if m is None else m.start()
                self.noise += j - i
                i = j
                continue
            got = self._frame_at(buf, i, n)
            if got is False:
                if not self._checked_frame_after(buf, i, n):
                    break  # a frame cut by the read: wait for the rest
                got = None
            if got is None:  # a magic byte that starts no frame: one byte of noise
                self.noise += 1
                i += 1
                continue
            size, msgid = got
            if msgid in keep:
                out.append(buf[i : i + size])
                self.passed += 1
            else:
                self.dropped += 1
            i += size
        self._held = buf[i:]
        return b"".join(out)

    def reset(self) -> None:
        """Forget a held partial frame (the link was re-opened)."""
        self._held = b""
