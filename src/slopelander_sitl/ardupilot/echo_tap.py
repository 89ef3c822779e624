"""The companion's lock-step echo, read off its link to ArduCopter and handed to the physics.

The companion answers a lock-stepped vehicle with TIMESYNC messages whose ``tc1`` is non-zero and
whose ``ts1`` is the newest vehicle time it has read, in nanoseconds
(``slopelander.controller.link.Link._timesync``); the link-fault relay sends the same during a cut.
ArduCopter drops them (``GCS_MAVLINK::handle_timesync`` answers only ``tc1 == 0`` and matches
answers to its own requests), so the pod reads them on the way in, on the companion's bridge, and
sends each time to the physics' gate (``slopelander_sitl.json_physics.companion_gate``), which holds
ArduCopter
while the companion is behind.
"""

from __future__ import annotations

import contextlib
import socket

from pymavlink import mavutil

from slopelander_sitl.json_physics.companion_gate import ECHO, GONE


class EchoTap:
    """One per connection (a MAVLink parser keeps state between chunks): call it with the bytes
    the companion sent."""

    def __init__(self, gate_port: int, host: str = "127.0.0.1") -> None:
        self.addr = (host, gate_port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.parser = mavutil.mavlink.MAVLink(None)
        self.parser.robust_parsing = True  # a damaged frame is skipped, never raised
        self.sent = 0

    def __call__(self, data: bytes) -> None:
        try:
            msgs = self.parser.parse_buffer(data) or []
        except Exception:  # a frame pymavlink cannot decode must not stop the bridge
            return
        for m in msgs:
            if m.get_msgId() == mavutil.mavlink.MAVLINK_MSG_ID_TIMESYNC and m.tc1 != 0 and m.ts1 > 0:
                try:
                    self.sock.sendto(ECHO.pack(m.ts1 // 1000), self.addr)
                    self.sent += 1
                except OSError:
                    pass  # the physics went away: the pod is stopping

    def close(self) -> None:
        """The companion disconnected: the physics stops waiting for it at once."""
        with contextlib.suppress(OSError):
            self.sock.sendto(ECHO.pack(GONE), self.addr)
        self.sock.close()
