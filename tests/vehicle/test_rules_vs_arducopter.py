"""The same command sequence (src/slopelander_sitl/vehicle/ack_sequence.py) sent live to real ArduCopter
SITL and to
the simulated vehicle: their COMMAND_ACK results must agree command by command, so the stand-in
cannot drift kinder than the firmware. Needs SLOPELANDER_ARDUCOPTER (the ArduCopter SITL binary)
and the launcher slopelander_sitl.ardupilot.launch; without the variable it is skipped and says why."""

from __future__ import annotations

import os

import pytest
from pymavlink import mavutil

from slopelander_sitl.vehicle.ack_sequence import run_sequence
from tests.vehicle.ack_compare import differences, standin_answers

BINARY = os.environ.get("SLOPELANDER_ARDUCOPTER")
pytestmark = [
    pytest.mark.skipif(
        not BINARY, reason="SLOPELANDER_ARDUCOPTER is not set: no ArduCopter SITL binary to compare with"
    ),
    pytest.mark.xdist_group("arducopter"),  # one ArduCopter at a time (tests/conftest.py)
]


def test_stand_in_answers_commands_as_arducopter_does():
    try:
        from slopelander_sitl.ardupilot.launch import start_arducopter
    except ImportError as exc:
        pytest.fail(f"SLOPELANDER_ARDUCOPTER is set but the launcher is missing: {exc}")
    with start_arducopter(speedup=4.0) as ap:
        conn = mavutil.mavlink_connection(ap.mavlink_url, source_system=255, source_component=190)
        try:
            assert conn.wait_heartbeat(timeout=60) is not None, "no HEARTBEAT from ArduCopter"
            real = run_sequence(conn, ready_timeout_s=180.0, text_after_ack_s=0.0)  # results compared
        finally:
            conn.close()
    stand_in = standin_answers()
    diff = differences(stand_in, [(a.name, a.result_name) for a in real])
    assert not diff, "stand-in vs ArduCopter:\n" + "\n".join(diff)
