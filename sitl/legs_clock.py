"""The companion's leg driver beside a lock-stepped simulator, on the vehicle's clock.

A lock-stepped vehicle runs only as fast as the machine lets the companion echo its time, and the
simulated board (``--clock external``) runs on that vehicle's time. On the wall clock a loaded
machine then reads as a silent board (:class:`slopelander.legs.driver.LegTimeout`); on the
vehicle's clock, as the landing controller measures it (``Lander`` sets it), it does not. The rig,
the flight tests and the benchmarks that open a driver themselves take it from here, so the rule
is written once.
"""

from __future__ import annotations

import time

from slopelander.controller.link import Link
from slopelander.legs.driver import LegBoard


def wait_vehicle_clock(link: Link, timeout_s: float = 30.0) -> None:
    """Poll ``link`` until the vehicle's clock is known (its first timestamped message arrived;
    ArduCopter's first one comes only after the streams are asked for); TimeoutError if none
    came within ``timeout_s`` of wall time: there is then no clock to measure the board on."""
    end = time.monotonic() + timeout_s
    while not link.clock.known and time.monotonic() < end:
        link.poll()
        time.sleep(0.002)
    if not link.clock.known:
        raise TimeoutError(f"the vehicle sent no timestamped message within {timeout_s:g} s")


def open_legs(port: str, link: Link, *, clock_timeout_s: float = 30.0, **kw) -> LegBoard:
    """Open the leg board on ``port`` and measure its timeouts on ``link``'s vehicle clock.

    The handshake waits on the wall clock (the board answers HELLO whatever its time), then every
    timeout and the board's silence are measured in vehicle time. ``kw`` goes to
    :meth:`LegBoard.open` (``calibration``, ``timeout``, ...)."""
    wait_vehicle_clock(link, clock_timeout_s)
    legs = LegBoard.open(port, **kw)
    legs.set_clock(link.clock.now)
    return legs
