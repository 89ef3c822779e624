"""What goes wrong on the link, and the frame-level decisions it makes (no sockets here)."""

from __future__ import annotations

import math
import random
from dataclasses import asdict, dataclass, fields


class FaultConfigError(ValueError):
    """A fault setting that cannot be applied (a probability outside 0..1, a negative delay)."""


@dataclass
class LinkFaults:
    """Per-frame fault probabilities and delays, applied to both directions.

    ``corrupt`` flips one byte of the payload or checksum, so the receiver's CRC check rejects the
    frame (what a noisy radio does); ``reorder`` holds a frame back until the next one has gone.
    """

    drop: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    corrupt: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        for f in ("drop", "duplicate", "reorder", "corrupt"):
            v = getattr(self, f)
            if not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
                raise FaultConfigError(f"{f} = {v!r}: a probability must lie within 0..1")
        for f in ("delay_s", "jitter_s"):
            v = getattr(self, f)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or not 0.0 <= v <= 60.0:
                raise FaultConfigError(f"{f} = {v!r}: must lie within 0..60 s")

    def updated(self, changes: dict) -> LinkFaults:
        known = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise FaultConfigError(f"unknown fault setting(s) {unknown}; known: {sorted(known)}")
        return LinkFaults(**{**asdict(self), **changes})


@dataclass
class Decision:
    """What happens to one frame: sent how many times, after what delay, with what bytes."""

    copies: int
    delay_s: float
    data: bytes
    hold: bool = False  # send after the next frame (reordering)


def decide(frame: bytes, faults: LinkFaults, rng: random.Random) -> Decision:
    """Draw the fate of one frame. Draws happen in a fixed order, so a seed reproduces a run."""
    u_drop, u_dup, u_reo, u_cor = rng.random(), rng.random(), rng.random(), rng.random()
    jitter = rng.uniform(0.0, faults.jitter_s) if faults.jitter_s > 0 else 0.0
    header = 10 if frame[:1] == b"\xfd" else 6  # MAVLink 2 / 1: corrupt the payload or CRC only
    pos = rng.randrange(header, len(frame)) if len(frame) > header else 0
    if u_drop < faults.drop:
        return Decision(0, 0.0, frame)
    data = frame
    if u_cor < faults.corrupt and pos:
        b = bytearray(frame)
        b[pos] ^= 0x5A
        data = bytes(b)
    return Decision(
        2 if u_dup < faults.duplicate else 1, faults.delay_s + jitter, data, u_reo < faults.reorder
    )
