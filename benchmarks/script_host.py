"""Cost and latency of the on-board script in the simulation's Lua host.

Runs the real `slopelander.lua` in `slopelander_sitl.vehicle.scripting.ScriptHost` on a 400 Hz vehicle clock
(as the simulated vehicle does) and prints:
- wall time per vehicle tick (host.run_due) with the script idle and with the reflex armed;
- vehicle time from a COMMAND_LONG handed to the host to the script's COMMAND_ACK and to the
  output override, over commands delivered at random phases of the script's schedule.

    python3 benchmarks/script_host.py --commands 200
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]

from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from slopelander_sitl.vehicle.scripting import RangeReading, ScriptHost  # noqa: E402

SCRIPT = ROOT / "firmware_params" / "scripts" / "slopelander.lua"
TICK_US = 2500  # 400 Hz


class Vehicle:
    """The least a vehicle must do for the script: a clock, armed, a range, records of output."""

    def __init__(self) -> None:
        self.us = 0
        self.acks: list[int] = []

    def time_ms(self) -> int:
        return self.us // 1000

    def time_us(self) -> int:
        return self.us

    def is_armed(self) -> bool:
        return True

    def arm(self) -> bool:
        return True

    def disarm(self) -> bool:
        return True

    def mode(self) -> int:
        return 4

    def set_mode(self, mode: int) -> bool:
        return False

    def emergency_stop(self) -> bool:
        return False

    def accel(self) -> tuple[float, float, float]:
        return (0.0, 0.0, -9.81)

    def gyro(self) -> tuple[float, float, float]:
        return (0.0, 0.0, 0.0)

    def rangefinder(self, orientation: int) -> RangeReading | None:
        return RangeReading(1.0, 4, 100, 0.1, 3.0) if orientation == 25 else None

    def rc_pwm(self, chan: int) -> int | None:
        return None

    def param(self, name: str) -> float | None:
        return None

    def set_param(self, name: str, value: float) -> bool:
        return False

    def send_text(self, severity: int, text: str) -> None:
        pass

    def send_named_float(self, name: str, value: float) -> None:
        pass

    def send_mavlink(self, chan: int, msgid: int, payload: bytes) -> bool:
        self.acks.append(self.us)
        return True

    def mixer_pwm(self, chan0: int) -> int:
        return 1600


def tick(host: ScriptHost, v: Vehicle) -> None:
    v.us += TICK_US
    host.run_due(v.time_ms())


def wall_per_tick(host: ScriptHost, v: Vehicle, ticks: int) -> float:
    t0 = time.perf_counter()
    for _ in range(ticks):
        tick(host, v)
    return (time.perf_counter() - t0) / ticks * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commands", type=int, default=200, help="commands for the latency figures")
    ap.add_argument("--ticks", type=int, default=8000, help="vehicle ticks for the cost figures")
    args = ap.parse_args()

    v = Vehicle()
    host = ScriptHost(SCRIPT, v)
    gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    rng = random.Random(1)

    def send(command: int, *p: float) -> None:
        msg = mavlink2.MAVLink_command_long_message(1, 1, command, 0, *p, *[0.0] * (7 - len(p)))
        msg.pack(gcs)
        host.deliver(msg, 0)

    idle = wall_per_tick(host, v, args.ticks)
    send(31011, 1, 0.3, 30, 100, 300, 10000)
    for _ in range(10):
        tick(host, v)
    armed = wall_per_tick(host, v, min(args.ticks, 3000))  # within the 10 s validity
    send(31011, 0)
    for _ in range(20):
        tick(host, v)

    to_ack, to_out = [], []
    for _ in range(args.commands):
        for _ in range(rng.randrange(1, 12)):  # a random phase of the script's 10 ms idle period
            tick(host, v)
        v.acks.clear()
        t_cmd = v.us
        send(31010, 1, 0, 40)
        while not v.acks or host.output_override(0, v.time_ms()) is None:
            tick(host, v)
            if host.output_override(0, v.time_ms()) is not None and len(to_out) < len(to_ack) + 1:
                to_out.append((v.us - t_cmd) / 1000)
        to_ack.append((v.acks[0] - t_cmd) / 1000)
        send(31010, 0)
        while host.output_override(0, v.time_ms()) is not None:
            tick(host, v)

    print(f"script host, 400 Hz vehicle clock, {SCRIPT.name}")
    print(f"wall time per tick: idle {idle:.1f} us, reflex armed {armed:.1f} us")
    for name, xs in (("command -> COMMAND_ACK", to_ack), ("command -> output override", to_out)):
        print(
            f"{name} (vehicle ms, n={len(xs)}): median {statistics.median(xs):.1f}, "
            f"max {max(xs):.1f}, min {min(xs):.1f}"
        )


if __name__ == "__main__":
    main()
