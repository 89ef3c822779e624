"""The lock-step echo, for a simulator that asks for it and for nothing else.

The project's simulated vehicle (``slopelander_sitl.vehicle --lockstep``) and its ArduCopter SITL rig (the
JSON physics' companion gate) run at most 50 ms of vehicle time ahead of the newest vehicle time
the companion echoed, so a simulated flight does not depend on how fast the machine runs the
companion. The echo is a TIMESYNC whose ``tc1`` is non-zero (an answer, not a request) and whose
``ts1`` is the newest vehicle time read, in nanoseconds, every 20 ms of vehicle time (or of local
time, when the vehicle's time has moved on less).

The companion has another link a simulator feeds on the vehicle's time: the leg board's, a
pseudo-terminal whose bytes a loaded machine can hold for seconds (the kernel's tty worker
unscheduled). While the board is not accounted for (:attr:`LockstepEcho.limit`: its newest frame,
or an unanswered command, more than :data:`BOARD_SLACK_S` of vehicle time back) the echo holds
at that time, so the simulator waits for the board's bytes as it waits for the companion, and
neither a silent-looking board nor a late acknowledgement is made of the machine's load. The
simulator then sends nothing; the link does not count that silence (:attr:`holding`). Before
holding, the companion reads what the board's line has in flight, waiting for the kernel
(:attr:`LockstepEcho.catch_up`): the wait is free, the simulator waits anyway. A hold
lasts at most :data:`HOLD_MAX_S` of local time (a board really gone is then found silent on the
vehicle's time, as without the hold).

The same time echoed again says "read everything, and the vehicle's time has not moved in
:data:`IDLE_S` of local time": the companion polls a drained link, so it is not behind, and a
simulator holding for a newer echo may run another lead (ArduCopter's gate,
``slopelander_sitl/json_physics/companion_gate.py``): what ArduCopter sent in its lead can sit
unsent while it is held, and both sides then waited for the other until the gate's patience ran
out (then 5 s; at the same vehicle time in two runs of a survey under load, 2026-12-07). Not while
the echo holds for the board: that wait is the companion's own.

A real autopilot has no use for it: ArduPilot drops a TIMESYNC answer that does not match a
request of its own (``GCS_MAVLINK::handle_timesync``), so on a real vehicle the echoes would only
load its serial link. The caller asks for the echo (``Link(lockstep=True)``: the test rig, the demo,
``slopelander land --lockstep`` against a lock-stepped simulator); the link never guesses.
"""

from __future__ import annotations

import math
from collections.abc import Callable

PERIOD_S = 0.02
#: vehicle seconds the board may be unaccounted for before the echo holds: one and a half of its
#: 100 ms STATUS periods. A board that keeps up does not trip it (the suite's flights took as
#: long as with 0.3 s on an idle machine), and it bounds how late, in vehicle time, the board's
#: news reaches the companion whatever the machine's load: with 0.3 s, two busy processes beside
#: the suite stretched a landing's wait for its legs from 0.3 to 0.9 s (2026-12-07)
BOARD_SLACK_S = 0.15
#: local seconds one hold may last
HOLD_MAX_S = 5.0
#: local seconds a polled, drained link may see the vehicle's time stand still before the newest
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
        self.repeats = 0  # the same time said again (see the module's note)
        self._last_usec = 0
        self._last_local = -math.inf  # local time of the last echo
        #: the vehicle time (s) up to which the companion's other links are accounted for (the
        #: leg board's: :meth:`slopelander.legs.driver.LegBoard.accounted_until`); None: no limit
        self.limit: Callable[[], float | None] | None = None
        #: called before the echo holds for :attr:`limit`: the companion reads what its other
        #: links have in flight, waiting for it (free: the simulator waits anyway)
        self.catch_up: Callable[[], None] | None = None
        #: local time the current hold began (None: not holding)
        self.held_since: float | None = None
        #: local time the last hold ended (the link counts silence from there)
        self.released_at = -math.inf
        self.holds = 0
        self._spent = False  # the current shortfall already held HOLD_MAX_S: not again

    @property
    def holding(self) -> bool:
        """Whether the echo is held for the board now (the simulator waits: its silence is ours)."""
        return self.held_since is not None

    def _target_usec(self) -> int:
        """The time to echo: the newest vehicle time, or the board's accounted time plus the
        slack if that is earlier (and the hold has not run out)."""
        now = self.clock.usec
        until = self.limit() if self.limit is not None else None

        def behind(until: float | None) -> bool:
            return until is not None and (until + BOARD_SLACK_S) * 1e6 < now

        short = behind(until)
        if short and self.catch_up is not None and not self._spent:
            self.catch_up()
            until = self.limit()
            short = behind(until)
        local = self.monotonic()
        if short and not self._spent:
            if self.held_since is None:
                self.held_since = local
                self.holds += 1
            if local - self.held_since <= HOLD_MAX_S:
                return min(now, int((until + BOARD_SLACK_S) * 1e6))
            self._spent = True  # the board is gone: let the vehicle's time find it silent
        if not short:
            self._spent = False
        if self.held_since is not None:
            self.held_since = None
            self.released_at = local
        return now

    def due(self) -> None:
        """Echo if the time to echo moved on since the last echo, by a period of vehicle time or
        after a period of local time: a simulator that holds for a newer echo sends nothing new
        (ArduCopter's last frames can sit in its buffers while it is held), so a newer time
        read before the hold, however little newer, must still be said (waiting for a period's
        worth of vehicle time, both sides waited for the other until the simulator's patience
        ran out: 5 s, on a loaded machine)."""
        if not self.clock.known:
            return
        target = self._target_usec()
        moved = target - self._last_usec
        idle = self.monotonic() - self._last_local
        if moved >= PERIOD_S * 1e6 or (moved > 0 and idle >= PERIOD_S):
            self.echo(target)
        elif idle >= IDLE_S and not self.holding and target == self.clock.usec:
            self.repeats += 1  # read dry, the vehicle's time still: say it again (a grant)
            self.echo(target)

    def echo(self, usec: int | None = None) -> None:
        """Echo ``usec`` (default: the newest vehicle time) now."""
        usec = self.clock.usec if usec is None else usec
        self._last_usec = usec
        self._last_local = self.monotonic()
        self.sent += 1
        self.conn.mav.timesync_send(max(1, int(self.monotonic() * 1e9)), usec * 1000)
