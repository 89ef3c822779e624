"""The scenario's pilot on ArduPilot's RC input: the channels a scenario's ``rc`` schedule names,
sent at their values for the physics time to SITL's UDP RC port (5501 + 10 x instance).

Without it ArduCopter reads its SITL defaults (throttle at 1000 µs, channel 8 at 1800 µs:
``AP_RCProtocol_UDP::set_default_pwm_input_values``), so a landing aborted to LOITER descended
onto the roof with the pilot's stick "held centred" in the scenario, and a switch the scenario
flips never reached the companion. The packet is ArduPilot's: 16 little-endian uint16, a 0 leaves
that channel as it was (``AP_RCProtocol_UDP::read_all_socket_input``); channels the scenario
never names are sent as 0, so ArduCopter keeps its own defaults for them (its flight-mode
channel among them).
"""

from __future__ import annotations

import socket
import struct

from slopelander_sitl.vehicle.scenario import Scenario

CHANNELS = 16
#: physics seconds between packets: ArduPilot takes RC input at 50 Hz and keeps the last packet
PERIOD_S = 0.02


class PilotRc:
    """Sends the scenario's RC channels to ``port`` on ``host``; :meth:`update` once per frame."""

    def __init__(self, scenario: Scenario, port: int, host: str = "127.0.0.1") -> None:
        self.scn = scenario
        self.addr = (host, port)
        self.named = sorted({ch for _, chans in scenario.rc for ch in chans if 1 <= ch <= CHANNELS})
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM) if self.named else None
        self.next_t = 0.0
        self.sent = 0

    def packet(self, t: float) -> bytes:
        """The 16 channels at physics time ``t``: the named ones' values, 0 (keep) for the rest."""
        values = [self.scn.rc_at(ch, t) if ch in self.named else 0 for ch in range(1, CHANNELS + 1)]
        return struct.pack(f"<{CHANNELS}H", *values)

    def update(self, t: float) -> None:
        """Send the channels when a period of physics time has passed (at once after a reset)."""
        if self.sock is None or (self.next_t - PERIOD_S < t < self.next_t):
            return
        self.next_t = t + PERIOD_S
        try:
            self.sock.sendto(self.packet(t), self.addr)
            self.sent += 1
        except OSError:
            pass  # ArduPilot not listening yet (booting): the next period sends again

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
