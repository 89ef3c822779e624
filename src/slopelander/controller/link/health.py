"""How the link is doing: the streams' delivered rates in vehicle time, and a reboot under it.

A stream is measured in the autopilot's own time (distinct samples per vehicle second), so a
simulation slowed by a loaded machine is not a failing stream; the landing refuses to start on a
stream delivering less than a share of what it asked for (:func:`stream_refusal`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

#: a reboot: this many messages in a row stamped more than ``REBOOT_BACK_S`` before the newest
#: vehicle time (one reordered or late frame is not; a relay holds back one frame at a time)
REBOOT_BACK_S = 1.0
REBOOT_RUN = 5
#: the shortest stretch of vehicle time a stream's delivered rate is measured over, and the longest
STREAM_MIN_SPAN_S = 0.5
STREAM_WINDOW_S = 2.0


@dataclass
class Stream:
    """One requested stream: what was asked, since when (vehicle s), the stamps delivered since."""

    name: str
    hz: float
    since: float
    stamps: deque = field(default_factory=lambda: deque(maxlen=1024))

    def add(self, t: float) -> None:
        """A sample stamped ``t`` (vehicle s); a duplicate or late frame is not a sample."""
        if not self.stamps or t > self.stamps[-1]:
            self.stamps.append(t)

    def delivered_hz(self, now: float, resumed_at: float) -> float | None:
        """Distinct samples per vehicle second over the last :data:`STREAM_WINDOW_S` since it was
        requested and since telemetry last resumed (``resumed_at``); None when less than
        :data:`STREAM_MIN_SPAN_S` of vehicle time has passed."""
        start = max(self.since, resumed_at, now - STREAM_WINDOW_S)
        span = now - start
        if span < STREAM_MIN_SPAN_S:
            return None
        return sum(1 for t in self.stamps if start < t <= now) / span


@dataclass
class Rate:
    """Arrival rate of one message type over a sliding window of local time."""

    stamps: deque = field(default_factory=lambda: deque(maxlen=400))

    def add(self, t: float) -> None:
        self.stamps.append(t)

    def hz(self, now: float, window: float = 2.0) -> float:
        n = sum(1 for s in self.stamps if now - s <= window)
        return n / window


class RebootWatch:
    """The autopilot rebooted when its messages keep coming stamped far before the newest vehicle
    time: its clock started again from zero (one late frame is not a reboot)."""

    def __init__(self) -> None:
        self.rebooted = False
        self.note: str | None = None
        self._behind = 0

    def observe(self, stamp_us: int, newest_us: int) -> None:
        """One stamped message (``stamp_us``) against the newest vehicle time (``newest_us``)."""
        if stamp_us < newest_us - REBOOT_BACK_S * 1e6:
            self._behind += 1
            if self._behind >= REBOOT_RUN and not self.rebooted:
                self.rebooted = True
                self.note = (
                    f"autopilot rebooted: its clock went back from {newest_us / 1e6:.1f} s "
                    f"to {stamp_us / 1e6:.1f} s"
                )
        else:
            self._behind = 0


def stream_refusal(link, min_fraction: float) -> str | None:
    """Why the requested streams cannot carry a landing, or None: the first stream delivering less
    than ``min_fraction`` of its requested rate in vehicle time (a refused request delivers
    nothing), or one not measured yet. None without a link (a machine stepped without one)."""
    streams = getattr(link, "streams", None)
    if link is None or not isinstance(streams, dict):
        return None
    for name, s in streams.items():
        got = link.delivered_hz(name)
        if got is None:
            return f"stream {name} not measured yet ({STREAM_MIN_SPAN_S:g} s of vehicle time needed)"
        if got < min_fraction * s.hz:
            return (
                f"stream {name} delivers {got:.1f} Hz of {s.hz:g} Hz requested (less than {min_fraction:.0%})"
            )
    return None
