"""ArduPilot SITL's external-physics ("JSON") wire format, both directions, without I/O.

ArduPilot sends one little-endian servo packet per physics frame: ``uint16 magic, uint16
frame_rate, uint32 frame_count, uint16 pwm[n]`` with magic 18458 for 16 channels and 29569 for
32. The physics answers with one JSON object per datagram, framed by a newline on both sides
(ArduPilot parses the text between the last two newlines it holds, so the leading one matters on
the first frame) and with compact separators (its parser reads vectors with ``"[%f, %f, %f]"``
right after ``"key":``, so a space after the colon breaks it).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from slopelander.errors import SlopelanderError

MAGIC_16 = 18458
MAGIC_32 = 29569
HEADER = struct.Struct("<HHI")
SIZES = {MAGIC_16: HEADER.size + 2 * 16, MAGIC_32: HEADER.size + 2 * 32}
_PWM = {MAGIC_16: struct.Struct("<16H"), MAGIC_32: struct.Struct("<32H")}


class ProtocolError(SlopelanderError):
    """A datagram that is not an ArduPilot servo packet, or a reply that cannot be sent."""


@dataclass(frozen=True)
class ServoFrame:
    frame_rate: int  # Hz: the physics step is 1 / frame_rate
    frame_count: int  # ArduPilot's count of replies it has consumed; restarts at 0
    pwm: tuple[int, ...]  # microseconds, 16 or 32 channels (0 = output not driven)

    @property
    def dt(self) -> float:
        return 1.0 / self.frame_rate


def encode_servo_packet(frame_rate: int, frame_count: int, pwm: list[int] | tuple[int, ...]) -> bytes:
    """ArduPilot's side: the packet for 16 or 32 channels (used by tests and benchmarks)."""
    if len(pwm) not in (16, 32):
        raise ProtocolError(f"a servo packet carries 16 or 32 channels, not {len(pwm)}")
    magic = MAGIC_16 if len(pwm) == 16 else MAGIC_32
    return HEADER.pack(magic, frame_rate, frame_count) + struct.pack(f"<{len(pwm)}H", *pwm)


def decode_servo_packet(data: bytes) -> ServoFrame:
    """The frame in one datagram; ProtocolError says what is wrong with anything else."""
    if len(data) < HEADER.size:
        raise ProtocolError(f"servo packet of {len(data)} bytes is shorter than its 8-byte header")
    magic, rate, count = HEADER.unpack_from(data)
    size = SIZES.get(magic)
    if size is None:
        raise ProtocolError(f"magic {magic} is not ArduPilot's ({MAGIC_16}: 16 channels, {MAGIC_32}: 32)")
    if len(data) != size:
        raise ProtocolError(f"servo packet with magic {magic} has {len(data)} bytes, expected {size}")
    if rate == 0:
        raise ProtocolError("servo packet with frame rate 0 Hz")
    return ServoFrame(rate, count, _PWM[magic].unpack_from(data, HEADER.size))


@dataclass(frozen=True)
class Fdm:
    """What the physics reports for one frame (SI units; body frame forward-right-down, world
    frame north-east-down)."""

    timestamp: float  # s since the physics started or last reset
    gyro: tuple[float, float, float]  # rad/s, body
    accel_body: tuple[float, float, float]  # m/s^2 specific force, body: level at rest (0, 0, -g)
    position: tuple[float, float, float]  # m, NED from home
    velocity: tuple[float, float, float]  # m/s, NED
    attitude: tuple[float, float, float]  # roll, pitch, yaw in rad
    rng_1: float | None = None  # m along the rangefinder beam; NaN = no data (a negative reads 0 m)


_REPLY = (
    '{"timestamp":%r,"imu":{"gyro":[%r,%r,%r],"accel_body":[%r,%r,%r]},'
    '"position":[%r,%r,%r],"velocity":[%r,%r,%r],"attitude":[%r,%r,%r]'
)
_FIELDS = ("timestamp", "imu.gyro", "imu.accel_body", "position", "velocity", "attitude")


def encode_reply(fdm: Fdm) -> bytes:
    """The datagram ArduPilot parses: "\\n{...}\\n", compact JSON, finite numbers only (a
    rangefinder without data is "nan").
    Formatted directly (float repr is JSON's number form): at 1,200 frames a second it costs
    less than ``json.dumps``."""
    values = (fdm.timestamp, *fdm.gyro, *fdm.accel_body, *fdm.position, *fdm.velocity, *fdm.attitude)
    values = tuple(map(float, values))
    # one check for all: a sum is finite only if every term is (short of 1e308, which no vehicle
    # reaches); the names are found only for the error
    if not math.isfinite(sum(values)) or (fdm.rng_1 is not None and math.isinf(fdm.rng_1)):
        bad = [_name(i) for i, v in enumerate(values) if not math.isfinite(v)]
        if fdm.rng_1 is not None and math.isinf(fdm.rng_1):
            bad.append("rng_1")
        raise ProtocolError(f"non-finite value in {', '.join(bad) or 'the sum'}: ArduPilot cannot parse it")
    text = _REPLY % values
    if fdm.rng_1 is not None:
        # "nan" is no JSON number, but ArduPilot reads each value with atof(), which takes it; its
        # SITL rangefinder reads NaN as "no data" (AP_RangeFinder_SITL.cpp)
        text += f',"rng_1":{float(fdm.rng_1)!r}'
    return b"\n" + text.encode("ascii") + b"}\n"


_PLANAR_REPLY = (
    '\n{"timestamp":%r,"imu":{"gyro":[%r,%r,%r],"accel_body":[%r,%r,%r]},'
    '"position":[%r,0.0,%r],"velocity":[%r,0.0,%r],"attitude":[0.0,%r,0.0],"rng_1":%r}\n'
)


def encode_planar_reply(values: tuple[float, ...]) -> bytes | None:
    """:func:`encode_reply`'s bytes for a planar vehicle's frame, whose east position, east
    velocity, roll and yaw are 0.0 and whose rangefinder value is given: ``values`` are
    (timestamp, gyro x3, accel_body x3, north, down, v_north, v_down, pitch, rng_1), all floats.
    The zeros are written as literals and the rest formatted once: a float's repr is most of
    the reply's cost. None when encode_reply would refuse the frame (a non-finite value): let
    it say why."""
    # the same test as encode_reply's: the zeros it also sums change no partial sum
    if not math.isfinite(sum(values[:12])) or math.isinf(values[12]):
        return None
    return (_PLANAR_REPLY % values).encode("ascii")


_FULL_REPLY = "\n" + _REPLY + ',"rng_1":%r}\n'


def encode_full_reply(values: tuple[float, ...]) -> bytes | None:
    """:func:`encode_reply`'s bytes for a frame with a rangefinder value, formatted once from the
    floats (timestamp, gyro x3, accel_body x3, position x3, velocity x3, attitude x3, rng_1):
    a float's repr is most of the reply's cost, an :class:`Fdm` built for it the rest. None when
    encode_reply would refuse the frame (a non-finite value): let it say why."""
    if not math.isfinite(sum(values[:16])) or math.isinf(values[16]):
        return None
    return (_FULL_REPLY % values).encode("ascii")


def _name(i: int) -> str:
    if i == 0:
        return "timestamp"
    return f"{_FIELDS[1 + (i - 1) // 3]}[{(i - 1) % 3}]"
