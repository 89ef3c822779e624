"""Time as the autopilot sees it, plus an injected wall clock for timeouts.

The controller reasons in vehicle time (the autopilot's own timestamps) so that a simulated vehicle
running faster or slower than real time, or stalled under CPU load, does not fool its timers. Link
loss is the one thing measured on the companion's own clock: a silent vehicle's time stands still.
"""

from __future__ import annotations

import time
from collections.abc import Callable


class VehicleClock:
    """Newest autopilot time seen (seconds since its boot) and the local time it arrived."""

    def __init__(self, monotonic: Callable[[], float] = time.monotonic) -> None:
        self.monotonic = monotonic
        self._usec: int | None = None
        self._local_at_update: float | None = None

    def observe_usec(self, time_usec: int) -> None:
        """Take a time_usec stamp; older stamps (reordered packets) are ignored."""
        if time_usec <= 0:
            return
        if self._usec is None or time_usec > self._usec:
            self._usec = int(time_usec)
            self._local_at_update = self.monotonic()

    def observe_boot_ms(self, time_boot_ms: int) -> None:
        """Take a time_boot_ms stamp."""
        self.observe_usec(int(time_boot_ms) * 1000)

    @property
    def known(self) -> bool:
        """Whether any autopilot time has been seen yet."""
        return self._usec is not None

    @property
    def usec(self) -> int:
        """Newest vehicle time in microseconds (0 before any)."""
        return self._usec or 0

    def now(self) -> float:
        """Newest vehicle time in seconds (0.0 before any)."""
        return self.usec / 1e6

    def local_age(self) -> float:
        """Local seconds since the vehicle time last advanced (inf before any)."""
        if self._local_at_update is None:
            return float("inf")
        return self.monotonic() - self._local_at_update


class ManualClock:
    """A monotonic clock a test advances by hand."""

    def __init__(self, start: float = 0.0) -> None:
        self.t = start

    def __call__(self) -> float:
        return self.t

    def advance(self, dt: float) -> None:
        """Move time forward by dt seconds."""
        if dt < 0:
            raise ValueError("time only moves forward")
        self.t += dt
