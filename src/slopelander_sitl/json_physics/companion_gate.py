"""Lock-step with the companion: the physics holds ArduPilot while the companion is behind.

ArduPilot SITL is lock-stepped with its JSON physics (it waits for each reply) but not with the
companion, so at a speed-up above 1, or on a loaded machine, the companion can fall behind the
vehicle by any amount: a second of vehicle time (the leg board's silence limit, the reflex's
validity) can pass while the companion is not scheduled. The project's simulated vehicle solves
this with the companion's TIMESYNC echo (``slopelander_sitl.vehicle --lockstep``: at most 50 ms of its time
ahead of the newest time the companion echoed); this gate gives ArduCopter the same rule from the
physics side. The echoes are read off the companion's link by ``slopelander_sitl.ardupilot.echo_tap`` and
arrive here as UDP datagrams of one little-endian int64: the echoed vehicle time in microseconds,
or ``GONE`` (-1) when the companion's connection closed.

Before stepping a frame that would put the physics more than ``lead_s`` past the newest echo, the
server waits for a newer one, or for the newest one said again during the wait: the companion
echoes the same time again when it has read its link dry and the vehicle's time has not moved
for a while (``slopelander.controller.link.lockstep``), so it is not behind; what ArduCopter sent
in the lead has not reached it (lost, or still unsent on the way: which, was not found). The
physics then runs another lead (a grant). An echo older than the newest says the same: during a
cut the test relay echoes in the companion's place (``slopelander_sitl.linkfault.relay``), up to
a time the companion never saw, since the cut dropped it; with the link back the companion's
echoes were older, and the physics held for the whole patience (15 s, 2026-12-07). Without the
grant both sides waited, each for the other, until the patience ran out: on a loaded machine the
physics held up to 4.8 s and the companion declared its link lost after 1.5 s (2026-12-07).
No echo yet (no companion, or one that does not echo): no waiting.
No newer echo for ``patience_s`` of wall time (the companion went away): the physics runs free
until the companion echoes again, as the simulated vehicle does.

Near the ground (``real_time_below_m`` of height over the surface under the vehicle, while a
companion echoes) the physics also keeps to real time, whatever ArduPilot's ``--speedup``: ArduPilot
SITL steps its clock in the main thread only, and every other thread, the on-board script's among
them, waits for it in 1 ms sleeps of wall time (``SITL_State::wait_clock``,
libraries/AP_HAL_SITL/SITL_State.cpp), so above real time the script runs late in vehicle time
(at 8x one landing's script saw the impact 170 ms after contact, against 7-10 ms at real time).
Above that height (take-off, transit, waiting for the legs) nothing the script does is timed,
and below it not everything is: real time is kept only while the script may be timing something
(:func:`script_may_time`: a descent, a fall, a landing still moving, reverse thrust) and for
``LINGER_S`` after. Still on the pad after the boot (arming, the motors spinning up), climbing
away, hovering for the legs or resting on the roof after a landing, the physics runs at
ArduPilot's speed-up. With real time on the whole 2 m, one 20 deg landing on ArduCopter slept
9.0 s of its 37 s (2026-11-27).

The lead is longer than the simulated vehicle's 50 ms: ArduCopter cannot be told to say the time
it waits at, and before the companion has asked for its streams the only stamped message it sends
is the script's SL_STATE at 5 Hz, so a lead under 200 ms could hold it before its next stamp.
"""

from __future__ import annotations

import math
import select
import socket
import struct
import time

ECHO = struct.Struct("<q")
#: the datagram's value when the companion disconnected: stop waiting for it now
GONE = -1
#: vehicle seconds the physics may run past the newest echo (see the module's note)
LEAD_S = 0.25
#: wall seconds without a newer echo after which the physics stops waiting: well past the
#: companion's own longest waits (its hold for the leg board and its handshake with it, 5 s
#: each). At 5 s, beside the suite and two busy processes, the gate gave up in 5 of 31 flights
#: and ArduCopter ran free through what the companion never saw (2026-12-07). A companion that
#: disconnects says so at once (``GONE``); a link cut is echoed by the relay.
PATIENCE_S = 15.0
#: a descent (m/s, down) or a pitch rate (rad/s) under these times nothing: resting, hovering
DESCENT_MPS = 0.15
PITCH_RATE_RAD_S = 0.2
#: physics seconds real time is kept after the script last may have timed something: the impact
#: is read on the filtered accelerometer after a contact that can stop the vehicle within a frame
LINGER_S = 1.0
#: physics seconds near the ground the physics may run above real time to catch up after falling
#: behind it. It caught up to 0.2 s after each hold for the companion; beside the suite and two
#: busy processes (818 holds in one ArduCopter flight) the script saw an impact 30 and 31 ms after
#: contact in two flights, against 7-10 ms at real time (2026-12-07): catching up is one way there
CATCH_UP_S = 0.005


def script_may_time(vz: float, pitch_rate: float, reversing: bool) -> bool:
    """Whether the on-board script may be timing something now (``vz`` up, world frame): the
    cut counts 20 Hz range samples in a descent, the impact is read in the fall and in the
    landing that follows (a slide descends, a pivot pitches), reverse thrust lasts its set time.
    Resting, hovering, climbing or moving level it times nothing."""
    return reversing or vz < -DESCENT_MPS or abs(pitch_rate) >= PITCH_RATE_RAD_S


class CompanionGate:
    """The echoes' UDP socket and the waiting rule; counts what it held."""

    def __init__(
        self,
        port: int,
        host: str = "127.0.0.1",
        lead_s: float = LEAD_S,
        patience_s: float = PATIENCE_S,
        real_time_below_m: float | None = None,
    ) -> None:
        if not (lead_s > 0 and patience_s > 0):
            raise ValueError(f"lead_s and patience_s must be positive, not {lead_s!r}, {patience_s!r}")
        if real_time_below_m is not None and not real_time_below_m > 0:
            raise ValueError(f"real_time_below_m must be positive, not {real_time_below_m!r}")
        self.real_time_below_m = real_time_below_m
        self._anchor: tuple[float, float] | None = None  # (physics t, wall) where real time began
        self._timed_until = -math.inf  # physics t until which real time is kept (LINGER_S)
        self.paced_s = 0.0  # wall time slept to keep to real time
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, port))
        except OSError:
            self.sock.close()
            raise
        self.sock.setblocking(False)
        self.port = self.sock.getsockname()[1]
        self.lead_s, self.patience_s = lead_s, patience_s
        self.echo_t: float | None = None  # newest echoed vehicle time (s)
        self.repeated = False  # the newest echo said again since the wait began
        self.free_until = -math.inf  # physics time up to which a grant lets the physics run
        self.grants = 0
        self.echo_wall = 0.0  # monotonic time it last moved forward
        self.echoes = 0
        self.holds = 0  # frames that waited
        self.held_s = 0.0  # wall time spent waiting
        self.give_ups = 0
        self.rejected = 0
        self.longest: tuple[float, float, float] = (0.0, 0.0, 0.0)  # (wall s, physics t, echo t)
        self.stopping = False  # set by the server on its way out: no more waiting

    def reset(self) -> None:
        """ArduPilot restarted: its old echoes mean nothing."""
        self.echo_t = None
        self.repeated = False
        self.free_until = -math.inf

    def _drain(self) -> None:
        """Read every echo waiting (none left, or the socket closed: done)."""
        while True:
            try:
                data = self.sock.recv(64)
            except OSError:  # BlockingIOError: nothing more waiting
                return
            if len(data) != ECHO.size:
                self.rejected += 1
                continue
            us = ECHO.unpack(data)[0]
            if us == GONE:
                self.echo_t = None
                continue
            t = us / 1e6
            self.echoes += 1
            if self.echo_t is None or t > self.echo_t:
                self.echo_t = t
                self.echo_wall = time.monotonic()
                self.repeated = False
            else:  # the newest said again, or an older one: the newest was the relay's (below)
                self.repeated = True

    def wait(self, t: float) -> None:
        """Return once physics time ``t`` is within the lead of the newest echo, or the companion
        has been silent for the patience (then run free until it echoes again)."""
        self._drain()
        if self.echo_t is None or t - self.echo_t <= self.lead_s or t <= self.free_until:
            return
        self.holds += 1
        self.repeated = False  # only a repeat sent while this frame waits says the companion waits too
        start, echo0 = time.monotonic(), self.echo_t
        try:
            while not self.stopping and self.echo_t is not None and t - self.echo_t > self.lead_s:
                left = self.patience_s - (time.monotonic() - self.echo_wall)
                if left <= 0:
                    self.give_ups += 1
                    self.echo_t = None
                    return
                select.select([self.sock], [], [], min(left, 0.2))
                self._drain()
                if self.repeated:  # the companion read everything and waits: run another lead
                    self.grants += 1
                    self.repeated = False
                    self.free_until = t + self.lead_s
                    return
        finally:
            took = time.monotonic() - start
            self.held_s += took
            if took > self.longest[0]:
                self.longest = (took, t, echo0)

    def pace(self, t: float, height_m: float, timed: bool = True) -> None:
        """Near the ground, with a companion echoing, while the script may be timing something
        (``timed``, :func:`script_may_time`) and ``LINGER_S`` after: do not run ahead of the wall
        clock, nor catch up more than ``CATCH_UP_S`` after falling behind (a hold for the
        companion, a stall): a catch-up runs above real time, where the script runs late."""
        below = self.real_time_below_m
        if timed:
            self._timed_until = t + LINGER_S
        if below is None or self.echo_t is None or not height_m < below or t > self._timed_until:
            self._anchor = None
            return
        now = time.monotonic()
        if self._anchor is None:
            self._anchor = (t, now)
            return
        ahead = (t - self._anchor[0]) - (now - self._anchor[1])
        if ahead > 0.001:
            time.sleep(ahead)
            self.paced_s += ahead
        elif ahead < -CATCH_UP_S:
            self._anchor = (t, now)

    def summary(self) -> str:
        took, t, echo = self.longest
        return (
            f"echoes={self.echoes} holds={self.holds} held={self.held_s:.1f}s "
            f"longest={took:.2f}s(t={t:.2f},echo={echo:.2f}) grants={self.grants} give_ups={self.give_ups} "
            f"bad_echoes={self.rejected} slept_near_ground={self.paced_s:.1f}s"
        )

    def close(self) -> None:
        self.sock.close()
