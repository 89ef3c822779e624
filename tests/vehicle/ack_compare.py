"""Run the command sequence (src/slopelander_sitl/vehicle/ack_sequence.py) on the simulated vehicle, and
compare
two runs' answers command by command (helpers for the tests, no test logic of their own)."""

from __future__ import annotations

import json
from pathlib import Path

from pymavlink import mavutil

from slopelander_sitl.vehicle.ack_sequence import Answer, run_sequence
from slopelander_sitl.vehicle.launch import start_vehicle

REFERENCE = Path(__file__).parent / "data" / "arducopter_command_acks.json"


def standin_answers(speed: float = 2.0) -> list[Answer]:
    """The sequence's answers from a simulated vehicle with the shipped parameters and script."""
    with start_vehicle(speed=speed) as v:
        conn = mavutil.mavlink_connection(v.mavlink_url, source_system=255, source_component=190)
        try:
            assert conn.wait_heartbeat(timeout=30) is not None
            return run_sequence(conn, text_after_ack_s=0.0)  # the results are compared, not the texts
        finally:
            conn.close()


def differences(got: list[Answer], want: list[tuple[str, str]]) -> list[str]:
    """Lines 'name: got X, ArduCopter Y' for every command whose result differs (or is missing)."""
    out = []
    got_by = {a.name: a.result_name for a in got}
    for name, result in want:
        if got_by.get(name) != result:
            out.append(f"{name}: stand-in {got_by.get(name, 'not sent')}, ArduCopter {result}")
    extra = set(got_by) - {n for n, _ in want}
    out += [f"{n}: sent to the stand-in only" for n in sorted(extra)]
    return out


def reference() -> tuple[str, list[tuple[str, str]]]:
    """The answers real ArduCopter SITL gave, recorded with its provenance."""
    data = json.loads(REFERENCE.read_text())
    return data["source"], [(a["name"], a["result"]) for a in data["answers"]]
