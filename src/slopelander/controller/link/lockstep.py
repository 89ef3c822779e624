"""The lock-step echo, for a simulator that asks for it and for nothing else.

The project's simulated vehicle (``slopelander_sitl.vehicle --lockstep``) and its ArduCopter SITL rig (the
JSON physics' companion gate) run at most 50 ms of vehicle time ahead of the newest vehicle time
the companion echoed, so a simulated flight does not depend on how fast the machine runs the
companion. The echo is a TIMESYNC whose ``tc1`` is non-zero (an answer, not a request) and whose
``ts1`` is the newest vehicle time read, in nanoseconds, every 20 ms of vehicle time.

A real autopilot has no use for it: ArduPilot drops a TIMESYNC answer that does not match a
request of its own (``GCS_MAVLINK::handle_timesync``), so on a real vehicle the echoes would only
load its serial link. The caller asks for the echo (``Link(lockstep=True)``: the test rig, the demo,
``slopelander land --lockstep`` against a lock-stepped simulator); the link never guesses.
"""

from __future__ import annotations

from collections.abc import Callable

PERIOD_S = 0.02


class LockstepEcho:
    """Sends the echo on ``conn`` whenever ``clock`` (a :class:`VehicleClock`) moved on
    :data:`PERIOD_S` since the last one."""

    def __init__(self, conn, clock, monotonic: Callable[[], float]) -> None:
        self.conn = conn
        self.clock = clock
        self.monotonic = monotonic
        self.sent = 0
        self._last_usec = 0

    def due(self) -> None:
        """Echo if the vehicle's time moved on a period since the last echo."""
        if self.clock.known and self.clock.usec - self._last_usec >= PERIOD_S * 1e6:
            self.echo()

    def echo(self) -> None:
        """Echo the newest vehicle time now."""
        self._last_usec = self.clock.usec
        self.sent += 1
        self.conn.mav.timesync_send(max(1, int(self.monotonic() * 1e9)), self.clock.usec * 1000)
