"""The wire format on its own: ArduPilot's servo packets byte for byte, and replies as
ArduPilot's parser reads them (including the framing and spacing it cannot read)."""

from __future__ import annotations

import dataclasses
import json
import math
import struct

import pytest

from slopelander_sitl.json_physics.ardupilot_side import EULER_ATT, parse_sensors
from slopelander_sitl.json_physics.protocol import (
    Fdm,
    ProtocolError,
    decode_servo_packet,
    encode_reply,
    encode_servo_packet,
)

FDM = Fdm(
    timestamp=12.345678901234,
    gyro=(0.01, -0.25, 1e-7),
    accel_body=(0.5, 0.0, -9.81),
    position=(1.25, 0.0, -2.5),
    velocity=(0.1, 0.0, 0.5),
    attitude=(0.0, -0.3, 0.0),
    rng_1=1.75,
)


def test_16_channel_packet_is_laid_out_as_ardupilot_sends_it() -> None:
    pwm = [1100 + i for i in range(16)]
    raw = struct.pack("<HHI16H", 18458, 1200, 77, *pwm)  # uint16 magic, rate; uint32 count; pwm[16]
    assert len(raw) == 40
    assert encode_servo_packet(1200, 77, pwm) == raw
    f = decode_servo_packet(raw)
    assert (f.frame_rate, f.frame_count, f.pwm) == (1200, 77, tuple(pwm))
    assert f.dt == pytest.approx(1 / 1200)


def test_32_channel_packet_has_its_own_magic() -> None:
    pwm = [1000 + 10 * i for i in range(32)]
    raw = struct.pack("<HHI32H", 29569, 400, 2**32 - 1, *pwm)
    assert len(raw) == 72
    assert encode_servo_packet(400, 2**32 - 1, pwm) == raw
    f = decode_servo_packet(raw)
    assert (f.frame_rate, f.frame_count, f.pwm) == (400, 2**32 - 1, tuple(pwm))


@pytest.mark.parametrize(
    ("raw", "words"),
    [
        (b"\x1a\x48", "shorter than its 8-byte header"),
        (struct.pack("<HHI16H", 1234, 1200, 0, *[1500] * 16), "magic 1234"),
        (struct.pack("<HHI16H", 29569, 1200, 0, *[1500] * 16), "expected 72"),
        (struct.pack("<HHI32H", 18458, 1200, 0, *[1500] * 32), "expected 40"),
        (struct.pack("<HHI16H", 18458, 1200, 0, *[1500] * 16) + b"\0", "41 bytes"),
        (struct.pack("<HHI16H", 18458, 0, 0, *[1500] * 16), "frame rate 0"),
    ],
)
def test_anything_else_is_refused_with_the_reason(raw: bytes, words: str) -> None:
    with pytest.raises(ProtocolError, match=words):
        decode_servo_packet(raw)


def test_reply_is_one_compact_object_between_newlines() -> None:
    raw = encode_reply(FDM)
    assert raw.startswith(b"\n") and raw.endswith(b"\n") and raw.count(b"\n") == 2
    assert b": " not in raw and b", " not in raw
    obj = json.loads(raw)
    assert obj["imu"]["accel_body"] == [0.5, 0.0, -9.81]
    assert obj["timestamp"] == FDM.timestamp
    assert raw.strip(b"\n") == json.dumps(obj, separators=(",", ":")).encode()  # exactly compact JSON


def test_ardupilots_parser_reads_every_field_with_its_type() -> None:
    found, v = parse_sensors(encode_reply(FDM).strip(b"\n"))
    names = {"timestamp", "imu.gyro", "imu.accel_body", "position", "attitude", "velocity", "rng_1"}
    assert set(v) == names
    assert found & EULER_ATT
    assert v["timestamp"] == FDM.timestamp  # double: every digit kept
    assert v["position"] == list(FDM.position)  # Vector3d
    assert v["imu.gyro"][2] == pytest.approx(1e-7, rel=1e-6)  # float32, exponent form read
    assert v["imu.accel_body"] == pytest.approx(list(FDM.accel_body), rel=1e-6)
    assert v["attitude"] == pytest.approx(list(FDM.attitude), rel=1e-6)
    assert v["rng_1"] == pytest.approx(1.75)


def test_the_parser_refuses_what_ardupilot_refuses() -> None:
    spaced = json.dumps(json.loads(encode_reply(FDM))).encode()  # default ", " and ": "
    found, v = parse_sensors(spaced)
    assert found != 0 and not found & EULER_ATT and "imu.gyro" not in v  # stops at the first vector
    missing = encode_reply(FDM).replace(b'"velocity"', b'"v"').strip(b"\n")
    assert parse_sensors(missing)[0] == 0


def test_non_finite_values_are_never_sent_but_a_rangefinder_without_data_is_nan() -> None:
    bad = Fdm(1.0, (0.0, math.nan, 0.0), (0.0, 0.0, -9.81), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    with pytest.raises(ProtocolError, match=r"in imu\.gyro\[1\]:"):
        encode_reply(bad)
    with pytest.raises(ProtocolError, match=r"in timestamp, rng_1:"):
        encode_reply(dataclasses.replace(FDM, timestamp=math.inf, rng_1=math.inf))
    # "nan" is what ArduPilot's SITL rangefinder reads as no data (it parses each value with atof)
    assert b'"rng_1":nan}' in encode_reply(dataclasses.replace(FDM, rng_1=math.nan))


def test_the_physics_fast_reply_is_the_reply_of_its_report() -> None:
    """``JsonPhysics.reply`` formats the frame without building the report (``fdm``): the same
    bytes as ``encode_reply(fdm())`` on the pad, climbing, falling back and in contact, with
    noise, wind and a fault window."""
    from slopelander_sitl.json_physics.physics import JsonPhysics
    from slopelander_sitl.vehicle.scenario import scenario_from_dict

    scn = scenario_from_dict(
        {
            "slope_deg": 20.0,
            "seed": 3,
            "wind": {"steady": {"fx_n": 1.5, "fz_n": 0.0}},
            "faults": [{"kind": "rangefinder_dropout", "start": 0.5, "end": 0.8}],
        }
    )
    physics = JsonPhysics(scn)
    frames = [1500] * 400 + [1900] * 800 + [1500] * 1600  # rest, climb, cut: fall back onto the pad
    for n, pwm in enumerate(frames):
        physics.step(1 / 800, (pwm,) * 4)
        assert physics.reply() == encode_reply(physics.fdm()), n
