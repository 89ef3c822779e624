"""Drop unwanted MAVLink frames by message id before pymavlink decodes them.

Decoding a message in Python (CRC, unpacking, a message object) is most of the companion's CPU at
the full IMU rate, and an autopilot streams more than a landing reads (its serial ports' SRn_
rates, a second IMU message, telemetry for the ground station). The message id sits in the frame
header: MAVLink 2 (``0xFD``) bytes 7..9, little-endian; MAVLink 1 (``0xFE``) byte 5. A frame whose
id is not kept is skipped whole, by its length byte, without its CRC being checked: a corrupt
frame that is dropped would have been refused anyway, and the frames that are kept go to
pymavlink whole, where the CRC (and a signature, when signing is on) is checked as before.

Frame lengths: MAVLink 2 is 10 header + payload + 2 CRC, + 13 when the signed flag (incompat bit 0)
is set; MAVLink 1 is 6 header + payload + 2 CRC. Bytes outside a frame (line noise, a partial frame
at start-up) are passed on, so pymavlink reports them as bad data as it would have; a frame cut at
the end of a read is held until the rest arrives.
"""

from __future__ import annotations

from collections.abc import Iterable

STX_V2 = 0xFD
STX_V1 = 0xFE
_HEADER_V2, _HEADER_V1 = 10, 6
_SIGNATURE = 13
_CRC = 2


class FrameFilter:
    """Feed raw link bytes; get back only the frames whose message id is in ``keep``."""

    def __init__(self, keep: Iterable[int]) -> None:
        self.keep = frozenset(int(k) for k in keep)
        if not self.keep:
            raise ValueError("a frame filter that keeps no message id would silence the link")
        self._held = b""
        #: frames skipped and frames passed since start (for the benchmark and the tests)
        self.dropped = 0
        self.passed = 0

    def feed(self, data: bytes) -> bytes:
        """The kept part of ``held + data``; an incomplete last frame is held for the next call."""
        buf = self._held + data if self._held else bytes(data)
        out: list[bytes] = []
        i, n = 0, len(buf)
        keep = self.keep
        while i < n:
            b = buf[i]
            if b == STX_V2:
                if n - i < _HEADER_V2:
                    break
                size = _HEADER_V2 + buf[i + 1] + _CRC + (_SIGNATURE if buf[i + 2] & 0x01 else 0)
                msgid = buf[i + 7] | buf[i + 8] << 8 | buf[i + 9] << 16
            elif b == STX_V1:
                if n - i < _HEADER_V1:
                    break
                size = _HEADER_V1 + buf[i + 1] + _CRC
                msgid = buf[i + 5]
            else:  # not a frame start: pass the run of noise on up to the next marker
                j = i + 1
                while j < n and buf[j] != STX_V2 and buf[j] != STX_V1:
                    j += 1
                out.append(buf[i:j])
                i = j
                continue
            if n - i < size:
                break
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
