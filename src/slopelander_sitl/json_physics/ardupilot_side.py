"""ArduPilot SITL's side of the JSON interface, written from its documented behaviour, so that
tests and benchmarks can drive the physics server without an ArduPilot binary.

It does what ArduPilot's JSON model does each frame: send the servo packet (16 or 32
channels) from an unbound socket to the physics port; wait for a reply in 100 ms slices and,
after a second without one, send the same packet again; turn every newline it receives into a
NUL, parse the text between the last two NULs with a ``strstr``/``atof``/``sscanf`` parser
(float32 vectors, read as ``"[%f, %f, %f]"`` two characters after the key), insist on the
mandatory keys and on attitude or quaternion, and only then count the frame. A timestamp going
backwards is a physics reset: no time passes for that frame.
"""

from __future__ import annotations

import re
import socket
import struct
import time
from dataclasses import dataclass, field

from slopelander_sitl.json_physics.protocol import encode_servo_packet

UDP_TIMEOUT_S = 0.1
RESEND_AFTER_S = 1.0

# (section, key, type, required) in ArduPilot's order; the bit of a found key is its index
KEYTABLE = (
    ("", "timestamp", "double", True),
    ("imu", "gyro", "vec3f", True),
    ("imu", "accel_body", "vec3f", True),
    ("", "position", "vec3d", True),
    ("", "attitude", "vec3f", False),
    ("", "quaternion", "quat", False),
    ("", "velocity", "vec3f", True),
    ("", "rng_1", "float", False),
    ("", "rng_2", "float", False),
    ("", "rng_3", "float", False),
    ("", "rng_4", "float", False),
    ("", "rng_5", "float", False),
    ("", "rng_6", "float", False),
    ("windvane", "direction", "float", False),
    ("windvane", "speed", "float", False),
    ("", "airspeed", "float", False),
    ("", "no_time_sync", "bool", False),
)
EULER_ATT, QUAT_ATT = 1 << 4, 1 << 5
_FLOAT = re.compile(rb"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)", re.IGNORECASE)
_SPACE = b" \t\n\v\f\r"


def _strtod(text: bytes, i: int) -> tuple[float | None, int]:
    """C strtod at index i: leading white space skipped; (None, i) when no number starts there."""
    while i < len(text) and text[i] in _SPACE:
        i += 1
    m = _FLOAT.match(text, i)
    if m is None:
        return None, i
    return float(m.group().decode()), m.end()


def _f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def _scan_vector(text: bytes, i: int, n: int) -> list[float] | None:
    """sscanf(p, "[%f, %f, ...]"): a literal must match the very next character; the blank in
    ", " matches any run of white space; %f skips white space first."""
    if i >= len(text) or text[i : i + 1] != b"[":
        return None
    i += 1
    out = []
    for k in range(n):
        v, i = _strtod(text, i)
        if v is None:
            return None
        out.append(v)
        if k < n - 1:
            if text[i : i + 1] != b",":
                return None
            i += 1
            while i < len(text) and text[i] in _SPACE:
                i += 1
    return out


def parse_sensors(text: bytes) -> tuple[int, dict[str, object]]:
    """(bitmask of the keys found, their values) as ArduPilot's parser reads one line. A
    bitmask of 0 means a mandatory key was missing; a vector that does not scan stops the
    parse there, as it does in ArduPilot."""
    found = 0
    values: dict[str, object] = {}
    for bit, (section, key, kind, required) in enumerate(KEYTABLE):
        p = text.find(section.encode())
        if p < 0:
            if required:
                return 0, {}
            continue
        p += len(section) + 1
        q = text.find(key.encode(), p)
        if q < 0:
            if required:
                return 0, {}
            continue
        found |= 1 << bit
        p = q + len(key) + 2
        name = f"{section}.{key}" if section else key
        if kind in ("double", "float"):
            v, _ = _strtod(text, p)
            values[name] = 0.0 if v is None else (v if kind == "double" else _f32(v))
        elif kind == "bool":
            m = re.match(rb"\s*[+-]?\d+", text[p:])
            values[name] = bool(m and int(m.group()) != 0)
        else:
            n = 4 if kind == "quat" else 3
            vec = _scan_vector(text, p, n)
            if vec is None:
                return found, values
            values[name] = vec if kind == "vec3d" else [_f32(x) for x in vec]
    return found, values


@dataclass
class ArduPilotSide:
    """One simulated ArduPilot sending frames to the physics at ``port`` on 127.0.0.1."""

    port: int
    frame_rate: int = 1200
    channels: int = 16
    frame_counter: int = 0
    last_timestamp: float = 0.0
    time_now_us: float = 0.0
    physics_resets: int = 0  # timestamps that went backwards
    resends: int = 0  # servo packets sent again after a second without a reply
    rejected: int = 0  # lines that did not carry the mandatory keys
    drop_replies: int = 0  # test hook: discard this many replies as if the network lost them
    state: dict[str, object] = field(default_factory=dict)
    sock: socket.socket = field(init=False, repr=False)
    buffer: bytearray = field(default_factory=bytearray, repr=False)

    def __post_init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(UDP_TIMEOUT_S)

    def close(self) -> None:
        self.sock.close()

    def output_servos(self, pwm: list[int]) -> None:
        full = (list(pwm) + [0] * self.channels)[: self.channels]
        self.sock.sendto(
            encode_servo_packet(self.frame_rate, self.frame_counter, full), ("127.0.0.1", self.port)
        )

    def update(self, pwm: list[int], give_up_s: float = 10.0) -> dict[str, object]:
        """One frame: send, wait (re-sending every second), parse; the state after it."""
        self.output_servos(pwm)
        self.recv_fdm(pwm, give_up_s)
        return self.state

    def recv_fdm(self, pwm: list[int], give_up_s: float = 10.0) -> bool:
        """Wait for one datagram and parse the newest complete line; True if it was used."""
        start = waited = time.monotonic()
        while True:
            try:
                data = self.sock.recv(65000)
            except TimeoutError:
                data = b""
            if data and self.drop_replies > 0:
                self.drop_replies -= 1
                data = b""
            if data:
                break
            now = time.monotonic()
            if now - start > give_up_s:
                raise TimeoutError(f"no reply to frame {self.frame_counter} in {give_up_s} s")
            if now - waited > RESEND_AFTER_S:
                waited = now
                self.resends += 1
                self.output_servos(pwm)
        self.buffer += data.replace(b"\n", b"\0")
        p2 = self.buffer.rfind(b"\0")
        if p2 <= 0:
            return False
        p1 = self.buffer.rfind(b"\0", 0, p2)
        if p1 < 0:
            return False
        found, values = parse_sensors(bytes(self.buffer[p1 + 1 : p2]))
        if found == 0 or not found & (EULER_ATT | QUAT_ATT):
            self.rejected += 1
            return False
        del self.buffer[:p2]
        self.state = values
        ts = float(values["timestamp"])
        if ts < self.last_timestamp:
            self.physics_resets += 1
            dt = 0.0
        else:
            dt = ts - self.last_timestamp
        self.time_now_us += dt * 1e6
        self.last_timestamp = ts
        self.frame_counter += 1
        return True
