"""The lock-step echo, for a simulator that asks for it and for nothing else.

The project's simulated vehicle (``slopelander_sitl.vehicle --lockstep``) and its ArduCopter SITL rig (the
JSON physics' companion gate) run at most 50 ms of vehicle time ahead of the newest vehicle time
the companion echoed, so a simulated flight does not depend on how fast the machine runs the
companion. The echo is a TIMESYNC whose ``tc1`` is non-zero (an answer, not a request) and whose
``ts1`` is the newest vehicle time read, in nanoseconds, every 20 ms of vehicle time.

The same time echoed twice says "read everything, and the vehicle's time has not moved a period
in :data:`IDLE_S` of wall time": the companion is polling a drained link, so it is not behind.
A simulator holding for a newer echo learns so that the stamped messages it sent before the hold
have not arrived (lost, or still unsent on the way while it is held): without it both sides
wait, each for the other (on ArduCopter SITL under load the physics held up to 4.8 s and the
companion declared the link lost after 1.5 s, 2026-12-07).

A real autopilot has no use for it: ArduPilot drops a TIMESYNC answer that does not match a
request of its own (``GCS_MAVLINK::handle_timesync``), so on a real vehicle the echoes would only
load its serial link. The caller asks for the echo (``Link(lockstep=True)``: the test rig, the demo,
``slopelander land --lockstep`` against a lock-stepped simulator); the link never guesses.
"""

from __future__ import annotations

import math
from collections.abc import Callable

PERIOD_S = 0.02
#: wall seconds a polled, drained link may see the vehicle's time stand still before the newest
#: time is echoed again (see the module's note)
IDLE_S = 0.1


class LockstepEcho:
    """Sends the echo on ``conn`` whenever ``clock`` (a :class:`VehicleClock`) moved on
    :data:`PERIOD_S` since the last one."""

    def __init__(self, conn, clock, monotonic: Callable[[], float]) -> None:
        self.conn = conn
        self.clock = clock
        self.monotonic = monotonic
        self.sent = 0
        self.repeats = 0
        self._last_usec = 0
        self._last_wall = -math.inf

    def due(self) -> None:
        """Echo if the vehicle's time moved on a period since the last echo; if it moved less in
        :data:`IDLE_S` of wall time, echo the newest time and then the same again (the caller
        has just read the link dry: its poll)."""
        if not self.clock.known:
            return
        if self.clock.usec - self._last_usec >= PERIOD_S * 1e6:
            self.echo()
        elif self.monotonic() - self._last_wall >= IDLE_S:
            if self.clock.usec != self._last_usec:
                self.echo()  # the newest time first (it moved less than a period)
            self.repeats += 1
            self.echo()

    def echo(self) -> None:
        """Echo the newest vehicle time now."""
        self._last_usec = self.clock.usec
        self._last_wall = self.monotonic()
        self.sent += 1
        self.conn.mav.timesync_send(max(1, int(self.monotonic() * 1e9)), self.clock.usec * 1000)
