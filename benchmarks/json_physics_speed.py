"""Physics frames per second the JSON physics server sustains in lock-step with a client at
ArduPilot's 1,200 Hz frame rate (every frame waits for its reply, as ArduPilot does), over real
UDP on this machine, and how many times real time that is. Two clients: one that parses every
reply as ArduPilot's parser does (in Python, so it costs more than ArduPilot's C), and a bare
one that only waits for each datagram. Each is measured in several windows (median and best
printed: other work on the machine slows single windows), and the server's own CPU time per
frame (from /proc) gives the frames per CPU-second it needs. Prints the figures; takes about
40 s plus the start.

    python benchmarks/json_physics_speed.py [--seconds 4] [--repeats 3] [--legs]
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from slopelander_sitl.json_physics.ardupilot_side import ArduPilotSide  # noqa: E402
from slopelander_sitl.json_physics.launch import start_json_physics  # noqa: E402
from slopelander_sitl.json_physics.protocol import encode_servo_packet  # noqa: E402
from slopelander_sitl.vehicle.launch import start_legboard  # noqa: E402

RATE = 1200
HOVERISH = [1800, 1800, 1800, 1800]  # lifts off and climbs: flight, not resting contact


def parsing_client(port: int, seconds: float) -> float:
    ap = ArduPilotSide(port, frame_rate=RATE)
    try:
        for _ in range(200):  # warm-up, not counted
            ap.update([1525] * 4)
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            ap.update(HOVERISH)
            n += 1
        return n / (time.perf_counter() - t0)
    finally:
        ap.close()


def bare_client(port: int, seconds: float) -> float:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(2.0)
        frame, n = 0, 0
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            s.sendto(encode_servo_packet(RATE, frame, HOVERISH + [0] * 12), ("127.0.0.1", port))
            s.recv(65000)
            frame += 1
            n += 1
        return n / (time.perf_counter() - t0)


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=4.0, help="wall seconds per window")
    ap.add_argument("--repeats", type=int, default=3, help="windows per client")
    ap.add_argument("--legs", action="store_true", help="with the simulated leg board connected")
    a = ap.parse_args()
    lb = start_legboard() if a.legs else None
    srv = start_json_physics(legs=lb.control if lb else None)
    rows = []
    try:
        for name, client in (("ArduPilot-parsing client", parsing_client), ("bare client", bare_client)):
            fps, cpu_us = [], []
            for _ in range(a.repeats):
                c0, f0 = cpu_seconds(srv.proc.pid), time.perf_counter()
                rate = client(srv.port, a.seconds)  # a new client each time: the physics resets
                frames = rate * (time.perf_counter() - f0)
                fps.append(rate)
                cpu_us.append((cpu_seconds(srv.proc.pid) - c0) / frames * 1e6)
            rows.append((name, fps, cpu_us))
    finally:
        srv.stop()
        if lb is not None:
            lb.stop()
    legs = "with the leg board" if a.legs else "no leg board"
    print(
        f"JSON physics server in lock-step at {RATE} Hz frames "
        f"({legs}; {a.repeats} x {a.seconds:g} s windows):"
    )
    for name, fps, _cpu in rows:
        med, best = statistics.median(fps), max(fps)
        print(
            f"  {name:26s} median {med:6,.0f} frames/s ({med / RATE:4.2f}x real time), "
            f"best {best:6,.0f} ({best / RATE:4.2f}x)"
        )
    cpu = statistics.median(rows[-1][2])
    print(
        f"  server CPU per frame (bare client, median) {cpu:5.0f} us: {1e6 / cpu:6,.0f} frames per "
        f"CPU-second ({1e6 / cpu / RATE:4.2f}x real time on one free core)"
    )
    print(f"  load average at the end: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"server summary: {srv.summary}")


if __name__ == "__main__":
    main()
