"""Shared pieces for the firmware tests: the ArduPilot reference data, a time-driven vehicle that
the real on-board script runs against, and MAVLink encoding/decoding with pymavlink."""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass, field, replace
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from pymavlink.mavutil import x25crc

from slopelander_sitl.vehicle.scripting import RangeReading, ScriptHost

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "firmware_params" / "scripts" / "slopelander.lua"
PARM_FILES = [REPO / "firmware_params" / "f450-fsa.parm", REPO / "firmware_params" / "sitl.parm"]


def reference_dir() -> Path | None:
    """ArduPilot reference data: $SLOPELANDER_ARDUPILOT_REFERENCE, else ../shared/reference."""
    env = os.environ.get("SLOPELANDER_ARDUPILOT_REFERENCE")
    path = Path(env) if env else REPO.parent / "shared" / "reference"
    return path if path.is_dir() else None


@pytest.fixture
def reference() -> Path:
    path = reference_dir()
    if path is None:
        reason = "ArduPilot reference data not found (set SLOPELANDER_ARDUPILOT_REFERENCE)"
        print(reason)
        pytest.skip(reason)
    return path


@dataclass
class TestVehicle:
    """A vehicle driven by the test's clock: what the script reads is set by the test, what it
    sends is recorded."""

    __test__ = False

    now_ms: int = 0
    armed: bool = True
    estop: bool = False
    accel_body: tuple[float, float, float] = (0.0, 0.0, -9.81)
    #: what the sensor reads now; the script sees it as ArduCopter does, sampled every
    #: ``range_period_ms`` (20 Hz, ArduCopter/Copter.cpp) with the sample's reading time
    range: RangeReading | None = None
    range_period_ms: int = 50
    attitude_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_rads: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity: tuple[float, float, float] | None = (0.0, 0.0, 0.0)
    #: the autopilot's flight mode (GUIDED), what the script set it to, the velocity targets it
    #: sent (t, north, east, down), and whether GUIDED takes them
    flight_mode: int = 4
    modes_set: list[int] = field(default_factory=list)
    velocity_targets: list[tuple[int, float, float, float]] = field(default_factory=list)
    takes_velocity_targets: bool = True
    _sample: RangeReading | None = None
    params: dict[str, float] = field(default_factory=lambda: {"MAV_SYSID": 1.0})
    texts: list[tuple[int, int, str]] = field(default_factory=list)
    named: list[tuple[int, str, float]] = field(default_factory=list)
    sent: list[tuple[int, int, int, bytes]] = field(default_factory=list)

    def time_ms(self) -> int:
        return self.now_ms

    def time_us(self) -> int:
        return self.now_ms * 1000

    def is_armed(self) -> bool:
        return self.armed

    def arm(self) -> bool:
        self.armed = True
        return True

    def disarm(self) -> bool:
        self.armed = False
        return True

    def mode(self) -> int:
        return self.flight_mode

    def set_mode(self, mode: int) -> bool:
        self.modes_set.append(mode)
        self.flight_mode = mode
        return True

    def set_target_velocity_ned(self, north: float, east: float, down: float) -> bool:
        if self.flight_mode != 4 or not self.takes_velocity_targets:
            return False
        self.velocity_targets.append((self.now_ms, north, east, down))
        return True

    def emergency_stop(self) -> bool:
        return self.estop

    def accel(self) -> tuple[float, float, float]:
        return self.accel_body

    def gyro(self) -> tuple[float, float, float]:
        return self.gyro_rads

    def attitude(self) -> tuple[float, float, float]:
        return self.attitude_rad

    def velocity_ned(self) -> tuple[float, float, float] | None:
        return self.velocity

    def rangefinder(self, orientation: int) -> RangeReading | None:
        if orientation != 25 or self.range is None:
            return None
        due = self.now_ms - self.now_ms % self.range_period_ms
        if self._sample is None or self._sample.last_reading_ms != due:
            self._sample = replace(self.range, last_reading_ms=due)
        return self._sample

    def rc_pwm(self, chan: int) -> int | None:
        return None

    def param(self, name: str) -> float | None:
        return self.params.get(name)

    def set_param(self, name: str, value: float) -> bool:
        return False

    def send_text(self, severity: int, text: str) -> None:
        self.texts.append((self.now_ms, severity, text))

    def send_named_float(self, name: str, value: float) -> None:
        self.named.append((self.now_ms, name, value))

    def send_mavlink(self, chan: int, msgid: int, payload: bytes) -> bool:
        self.sent.append((self.now_ms, chan, msgid, payload))
        return True

    def mixer_pwm(self, chan0: int) -> int:
        return 1600

    # -- test conveniences -------------------------------------------------------------------
    def states(self) -> list[float]:
        return [v for _, n, v in self.named if n == "SL_STATE"]

    def state(self) -> float:
        return self.states()[-1]

    def sl_texts(self) -> list[str]:
        return [t for _, _, t in self.texts if t.startswith("SL: ")]


class Bench:
    """The real script in the real Lua host, with the clock advanced by the test."""

    def __init__(self, script: Path = SCRIPT, vehicle: TestVehicle | None = None) -> None:
        self.io = vehicle or TestVehicle()
        self.host = ScriptHost(script, self.io)
        self.gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
        self.request = 0

    def run(self, ms: int, each=None) -> None:
        """Advance the vehicle clock by `ms`, 1 ms per tick, the host scheduled every tick;
        `each(t_ms)` may change the vehicle's inputs before each tick."""
        for _ in range(ms):
            self.io.now_ms += 1
            if each is not None:
                each(self.io.now_ms)
            self.host.run_due(self.io.now_ms)

    def outputs(self) -> list[int | None]:
        return [self.host.output_override(ch, self.io.now_ms) for ch in range(4)]

    def command(
        self, command: int, *params: float, target=(1, 1), chan: int = 0, wait_ms: int = 20, request=None
    ):
        """Send a COMMAND_LONG to the script and return its decoded COMMAND_ACK; param 7 is the
        next request number (or ``request``), and the ACK must echo it in result_param2."""
        if request is None:
            self.request += 1
            request = self.request
        p = [*params, *[0.0] * (6 - len(params)), request]
        msg = mavlink2.MAVLink_command_long_message(target[0], target[1], command, 0, *p)
        msg.pack(self.gcs)
        before = len(self.io.sent)
        assert self.host.deliver(msg, chan)
        self.run(wait_ms)
        acks = [s for s in self.io.sent[before:] if s[2] == 77]
        assert len(acks) == 1, f"expected one COMMAND_ACK, got {len(acks)}"
        _, ack_chan, msgid, payload = acks[0]
        assert ack_chan == chan
        ack = decode(msgid, payload)
        expected = int(request) if request == request and float(request).is_integer() else None
        if ack.result != 2 and expected is not None:  # DENIED may be for the number itself
            assert ack.result_param2 == expected, "the ACK must echo the request number"
        return ack


def decode(msgid: int, payload: bytes):
    """Frame a payload the script sent as MAVLink 2 (sysid 1, compid 1) and parse it with pymavlink."""
    cls = mavlink2.mavlink_map[msgid]
    header = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, 0, 1, 1, msgid & 0xFFFF, msgid >> 16)
    crc = x25crc(header[1:] + payload)
    crc.accumulate([cls.crc_extra])
    frame = header + payload + struct.pack("<H", crc.crc)
    return mavlink2.MAVLink(None).decode(bytearray(frame))


@pytest.fixture
def bench() -> Bench:
    b = Bench()
    b.run(50)
    return b
