"""The simulated vehicle answers the companion's commands as real ArduCopter does: the scripted
sequence (src/slopelander_sitl/vehicle/ack_sequence.py: modes, arming, take-off, disarm before and after the
land detector fires, forced disarm, message intervals up to 400 Hz, a servo on a motor channel, an
unknown command) gets the same COMMAND_ACK result, command by command, as ArduCopter SITL
V4.7.0-dev gave it (tests/vehicle/data/arducopter_command_acks.json says how it was recorded;
tests/vehicle/test_rules_vs_arducopter.py runs both live when the binary is at hand)."""

from __future__ import annotations

from tests.vehicle.ack_compare import differences, reference, standin_answers


def test_stand_in_answers_as_recorded_arducopter():
    source, want = reference()
    got = standin_answers()
    diff = differences(got, want)
    assert not diff, f"against {source}:\n" + "\n".join(diff)
