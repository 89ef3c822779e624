"""The real script fed arbitrary COMMAND_LONG payloads (any length, any bytes, NaN and infinities
included): it keeps running, answers at most once, and never drives the motors outside what a
valid command allows, nor at all while disarmed."""

from __future__ import annotations

import struct

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import all as mavlink2
from pymavlink.generator.mavcrc import x25crc
from script_bench import Bench, decode

COMMAND_LONG = 76
ACTUATOR, REFLEX = 31010, 31011


class RawFrame:
    """A frame as ArduPilot hands it to a script: CRC valid, payload whatever the sender put in."""

    def __init__(self, payload: bytes) -> None:
        header = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, 0, 255, 190, COMMAND_LONG, 0)
        crc = x25crc(header[1:] + payload)
        crc.accumulate([mavlink2.MAVLink_command_long_message.crc_extra])
        self.buf = header + payload + struct.pack("<H", crc.crc)

    def get_msgId(self) -> int:  # noqa: N802 - pymavlink's name
        return COMMAND_LONG

    def get_msgbuf(self) -> bytes:
        return self.buf


def command_payload(draw) -> bytes:
    """Mostly our own commands with hostile parameters; sometimes plain random bytes."""
    if draw(st.booleans()):
        return draw(st.binary(min_size=0, max_size=40))
    f = st.one_of(
        st.floats(allow_nan=True, allow_infinity=True, width=32), st.sampled_from([0.0, 1.0, 2.0, 3.0, 100.0])
    )
    params = [draw(f) for _ in range(7)]
    cmd = draw(st.sampled_from([ACTUATOR, REFLEX, 400, 0, 65535]))
    target = draw(st.sampled_from([(1, 1), (0, 0), (1, 0), (2, 1), (255, 255)]))
    payload = struct.pack("<7fHBBB", *params, cmd, target[0], target[1], 0)
    cut = draw(st.integers(0, len(payload)))
    return payload[:cut] if draw(st.booleans()) else payload.rstrip(b"\0")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), armed=st.booleans())
def test_any_payload_leaves_the_script_running_and_the_outputs_safe(data, armed: bool) -> None:
    bench = Bench()
    bench.io.armed = armed
    bench.run(30)
    for _ in range(data.draw(st.integers(1, 4))):
        payload = data.draw(st.composite(lambda d: command_payload(d))())
        before = len(bench.io.sent)
        bench.host.deliver(RawFrame(payload), 0)
        bench.run(15)
        assert bench.host.running, bench.host.error
        acks = [s for s in bench.io.sent[before:] if s[2] == 77]
        assert len(acks) <= 1
        if acks:
            event(f"ack result {decode(acks[0][2], acks[0][3]).result}")
        for pwm in bench.outputs():
            assert pwm is None or 1000 <= pwm <= 1500  # stopped (1500) or reversed, never forward
            assert armed or pwm is None  # disarmed: the script refuses to drive the motors
