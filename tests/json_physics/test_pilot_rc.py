"""The scenario's pilot reaches ArduPilot's SITL RC input as ArduPilot reads it: 16 little-endian
uint16 channels in one UDP datagram, 0 for a channel the scenario never names (ArduPilot keeps
its own value: ``AP_RCProtocol_UDP::read_all_socket_input``)."""

from __future__ import annotations

import socket
import struct

from slopelander_sitl.json_physics.pilot_rc import PERIOD_S, PilotRc
from slopelander_sitl.vehicle.scenario import scenario_from_dict


def listener() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(2.0)
    return s


def test_the_named_channels_follow_the_schedule_in_physics_time_and_the_rest_are_left_alone():
    scn = scenario_from_dict(
        {"rc": [{"t": 0.0, "channels": {3: 1000, 8: 1500}}, {"t": 5.0, "channels": {3: 1500}}]}
    )
    rx = listener()
    rc = PilotRc(scn, rx.getsockname()[1])
    try:
        rc.update(0.0)
        first = struct.unpack("<16H", rx.recv(64))
        assert first[2] == 1000 and first[7] == 1500
        assert [v for i, v in enumerate(first) if i not in (2, 7)] == [0] * 14
        rc.update(PERIOD_S / 2)  # within the period: nothing sent
        rc.update(5.0)
        later = struct.unpack("<16H", rx.recv(64))
        assert later[2] == 1500 and later[7] == 1500
        assert rc.sent == 2
        rc.update(0.0)  # the physics reset (ArduPilot restarted): sent again at once
        assert struct.unpack("<16H", rx.recv(64))[2] == 1000
    finally:
        rc.close()
        rx.close()


def test_a_scenario_without_a_pilot_sends_nothing():
    rc = PilotRc(scenario_from_dict({}), 9)
    rc.update(0.0)
    assert rc.sock is None and rc.sent == 0
