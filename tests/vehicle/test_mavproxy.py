"""MAVProxy, the ground station users know, connects to the vehicle, sees its mode, changes it,
arms, reads and sets a parameter, and flies it with `takeoff` and `position`."""

from __future__ import annotations

import re
import shutil
import socket
import subprocess
import threading
import time

import pytest
from pymavlink import mavutil

from slopelander_sitl.vehicle.launch import start_vehicle
from tests.vehicle.conftest import ROUTE_A

pytestmark = pytest.mark.skipif(shutil.which("mavproxy.py") is None, reason="MAVProxy is not installed")


def test_mavproxy_mode_arm_param(tmp_path):
    v = start_vehicle(params=ROUTE_A, no_script=True)
    try:
        cmd = [
            "mavproxy.py",
            "--master",
            v.mavlink_url,
            "--nowait",
            "--default-modules=link,mode,arm,param",
            "--state-basedir",
            str(tmp_path),
        ]
        p = subprocess.Popen(
            cmd,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=tmp_path,
        )
        lines = _reader(p)
        _wait_for(lines, "Detected vehicle")  # before that MAVProxy maps mode names for another vehicle
        for c, answer in (
            ("mode GUIDED", "Mode GUIDED"),
            ("arm throttle", ARMED),  # on the heartbeat after the ACK
            ("param fetch MOT_PWM_MIN", "MOT_PWM_MIN = "),
            ("param set GUID_TIMEOUT 2.5", None),  # MAVProxy prints nothing: fetched below
        ):
            p.stdin.write(c + "\n")
            p.stdin.flush()
            if answer is not None:
                _wait_for(lines, answer, timeout=10.0)
        # the set is sent on its own time: fetched until it shows, for at most 5 s
        for _ in range(5):
            p.stdin.write("param fetch GUID_TIMEOUT\n")
            p.stdin.flush()
            if _wait_for(lines, "GUID_TIMEOUT = 2.5", timeout=1.0):
                break
        _stop(p)
        out = "\n".join(ln for _, ln in lines)
    finally:
        assert v.stop() == 0  # SIGTERM ends the vehicle cleanly
    assert "Detected vehicle 1:1" in out
    assert "Mode STABILIZE" in out
    assert "DO_SET_MODE: ACCEPTED" in out and "Mode GUIDED" in out
    assert "COMPONENT_ARM_DISARM: ACCEPTED" in out and "ARMED" in out
    assert "MOT_PWM_MIN = 1525.0" in out
    assert "GUID_TIMEOUT = 2.5" in out


def _reader(p: subprocess.Popen) -> list[tuple[float, str]]:
    """MAVProxy's output lines with their time since start, read on a thread as they come."""
    lines: list[tuple[float, str]] = []
    t0 = time.monotonic()

    def read() -> None:
        for ln in p.stdout:
            lines.append((time.monotonic() - t0, ln.rstrip()))

    threading.Thread(target=read, daemon=True).start()
    return lines


def _stop(p: subprocess.Popen) -> None:
    """End MAVProxy: its stdin closed and SIGTERM (it waits on its console otherwise), killed
    if it has not ended 10 s later."""
    p.stdin.close()
    p.terminate()
    try:
        p.wait(timeout=10)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()


#: MAVProxy's line when the vehicle's heartbeat says armed, after its prompt or not ("GUIDED> ARMED")
ARMED = re.compile(r"(^|> )ARMED$")


def _wait_for(lines: list[tuple[float, str]], text: str | re.Pattern, timeout: float = 60.0) -> bool:
    """Wait until a line holds ``text`` (or matches it); False when the timeout passed first (the
    test's assertions then say what is missing)."""
    found = text.search if isinstance(text, re.Pattern) else lambda ln: text in ln
    end = time.monotonic() + timeout
    while not any(found(ln) for _, ln in lines):
        if time.monotonic() >= end:
            return False
        time.sleep(0.05)
    return True


def _settled_at(conn, ok, timeout: float) -> object | None:
    """The first LOCAL_POSITION_NED for which ``ok`` holds with the vehicle nearly still (under
    0.1 m/s), or the last one seen when the timeout passes first."""
    last, end = None, time.monotonic() + timeout
    while time.monotonic() < end:
        m = conn.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=0.1)
        if m is None:
            continue
        last = m
        if ok(m) and abs(m.vx) < 0.1 and abs(m.vy) < 0.1 and abs(m.vz) < 0.1:
            return m
    return last


def test_mavproxy_flies_the_vehicle_with_position_no_false_fence_breach_quick_parameters(tmp_path):
    """The README's "Using it" flow from MAVProxy: GUIDED, arm, take off, then `position 1.5 0 0`
    (a BODY_NED offset, as ArduCopter takes it) moves the vehicle 1.5 m north. On connect MAVProxy
    reports no fence breach (the geofence health bit, as ArduPilot sets it without a fence) and
    its parameter download does not wait out FTP time-outs (the stand-in answers FTP at once)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    watch = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}")
    v = start_vehicle(params=ROUTE_A, no_script=True, extra_endpoints=[f"udpout:127.0.0.1:{port}"])
    p = subprocess.Popen(
        ["mavproxy.py", "--master", v.mavlink_url, "--nowait", "--state-basedir", str(tmp_path)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=tmp_path,
    )
    lines = _reader(p)

    def seen(text: str) -> float | None:
        return next((t for t, ln in lines if text in ln), None)

    try:
        _wait_for(lines, "Detected vehicle")
        _wait_for(lines, "parameters", timeout=10.0)  # the download, whose time is checked below
        for c, answer in (
            ("mode GUIDED", "Mode GUIDED"),
            ("arm throttle", "COMPONENT_ARM_DISARM"),
            ("takeoff 2", "NAV_TAKEOFF"),
        ):
            p.stdin.write(c + "\n")
            p.stdin.flush()
            _wait_for(lines, answer, timeout=10.0)
        start = _settled_at(watch, lambda m: m.z < -1.8, timeout=20.0)  # at 2 m, hovering
        p.stdin.write("position 1.5 0 0\n")
        p.stdin.flush()
        end = _settled_at(watch, lambda m: start is not None and m.x - start.x > 1.25, timeout=20.0)
    finally:
        _stop(p)
        watch.close()
        v.stop()
    out = "\n".join(f"{t:5.1f} {ln}" for t, ln in lines)
    detected, params = seen("Detected vehicle"), seen("parameters")
    assert detected is not None, out
    assert "fence breach" not in out, out
    assert params is not None and params - detected < 5.0, out  # one FTP time-out alone is 2 s
    assert "FTP: request timed out" not in out, out
    assert "NAV_TAKEOFF: ACCEPTED" in out, out
    assert start is not None and end is not None
    assert abs(end.x - start.x - 1.5) < 0.25, (start, end)
