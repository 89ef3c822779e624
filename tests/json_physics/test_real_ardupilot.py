"""Real ArduCopter SITL (``SLOPELANDER_ARDUCOPTER``; ``.ci/run`` points it at the shared build)
boots on slopelander's physics through :func:`slopelander_sitl.ardupilot.start_arducopter`, which runs it in a
loopback-only network namespace of its own, in its own temporary folder: its MAVLink shows the
physics (level on the pad, the rangefinder reading the leg height), the on-board script announces
itself, and the rangefinder's "no data" reaches it as no data.
"""

from __future__ import annotations

import os
import time

import pytest

from slopelander_sitl.ardupilot import arducopter_binary, start_arducopter
from slopelander_sitl.ardupilot.launch import ArduCopterMissingError

# one ArduCopter at a time; long flights (tests/conftest.py)
pytestmark = [pytest.mark.xdist_group("arducopter"), pytest.mark.timeout(1200)]

os.environ.setdefault("MAVLINK20", "1")


def _binary():
    try:
        return arducopter_binary()
    except ArduCopterMissingError as exc:
        if os.environ.get("SLOPELANDER_ARDUCOPTER"):
            pytest.fail(str(exc))  # named but not usable: a broken set-up, not a missing one
        pytest.skip(str(exc))


def _collect(conn, types: list[str], until, timeout_s: float = 90.0) -> dict:
    seen: dict[str, object] = {}
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and not until(seen):
        m = conn.recv_match(type=types, blocking=True, timeout=1)
        if m is None:
            continue
        if m.get_type() == "NAMED_VALUE_FLOAT":
            seen.setdefault("script_" + m.name, m.value)
        else:
            seen[m.get_type()] = m
    return seen


def test_it_boots_fast_and_is_handed_over_at_real_time_ready_to_arm_in_guided() -> None:
    """The fast boot (src/slopelander_sitl/ardupilot/fast_boot.py) on the real binary: ready once it could
    arm,
    at the flight's speed-up, and then it arms in GUIDED at the first asking."""
    binary = _binary()
    from pymavlink import mavutil

    from slopelander_sitl.guided import GUIDED, THROTTLE_DOWN_US, throttle_channels

    t0 = time.monotonic()
    with start_arducopter(binary=binary, speedup=1.0) as ap:
        boot_wall = time.monotonic() - t0
        assert "pre-arm checks pass, EKF has a position; now at speed-up 1" in ap.ready_line, ap.ready_line
        booted = float(ap.ready_line.split("boot=")[1].split("s")[0])
        assert booted > 30.0  # the EKF's position comes at 38-41 s of vehicle time
        assert boot_wall < booted, (boot_wall, booted)  # faster than real time
        conn = mavutil.mavlink_connection(ap.gcs_url, source_system=255, source_component=190)
        try:
            assert conn.wait_heartbeat(timeout=30) is not None
            conn.mav.command_long_send(1, 1, 511, 0, 2, 100_000, 0, 0, 0, 0, 0)  # SYSTEM_TIME
            first = conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=10)
            w0 = time.monotonic()
            last = first
            while time.monotonic() - w0 < 3.0:  # the newest SYSTEM_TIME after 3 s of wall time
                m = conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=0.5)
                last = m or last
            rate = (last.time_boot_ms - first.time_boot_ms) / 1000.0 / (time.monotonic() - w0)
            assert 0.5 < rate < 1.3, rate  # real time, not the boot's speed-up
            conn.mav.command_long_send(1, 1, 176, 0, 1, GUIDED, 0, 0, 0, 0, 0)  # DO_SET_MODE
            ack = conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
            assert ack is not None and ack.result == 0, ack
            conn.mav.rc_channels_override_send(1, 1, *throttle_channels(THROTTLE_DOWN_US))
            conn.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)  # arm, no force
            ack = conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
            assert ack is not None and ack.command == 400 and ack.result == 0, (ack, ap.statustexts()[-3:])
        finally:
            conn.close()


def test_arducopter_flies_on_slopelanders_physics_in_its_own_namespace() -> None:
    binary = _binary()
    from pymavlink import mavutil

    quiet = {"noise": {"accel": 0.0, "gyro": 0.0, "range": 0.0}}
    with start_arducopter(scenario=quiet, binary=binary, boot_speedup=None) as ap:  # no arming
        conn = mavutil.mavlink_connection(ap.mavlink_url, source_system=255)
        try:
            assert conn.wait_heartbeat(timeout=30) is not None
            for msg_id in (30, 132):  # ATTITUDE, DISTANCE_SENSOR
                conn.mav.command_long_send(1, 1, 511, 0, msg_id, 100_000, 0, 0, 0, 0, 0)
            seen = _collect(
                conn,
                ["ATTITUDE", "DISTANCE_SENSOR", "NAMED_VALUE_FLOAT"],
                lambda s: {"ATTITUDE", "DISTANCE_SENSOR", "script_SL_STATE"} <= set(s),
            )
        finally:
            conn.close()
        # its STATUSTEXTs are logged with the boot time they came at (not 0: the console's
        # request for SYSTEM_TIME went unanswered while ArduCopter booted). The EKF's origin comes
        # tens of seconds after boot; the texts of its first second may still read 0.
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline and not any("origin set" in ln for ln in ap.statustexts()):
            time.sleep(0.5)
        ekf = [ln for ln in ap.statustexts() if "origin set" in ln]
        assert ekf and float(ekf[0].split()[0]) > 0.0, ap.statustexts()
        # ArduCopter's folder is its own, and it ran with no network but loopback
        assert (ap.folder / "eeprom.bin").exists()
        assert (ap.folder / "scripts" / "slopelander.lua").exists()
    assert {"ATTITUDE", "DISTANCE_SENSOR", "script_SL_STATE"} <= set(seen), sorted(seen)
    assert abs(seen["ATTITUDE"].pitch) < 0.05 and abs(seen["ATTITUDE"].roll) < 0.05
    assert 5 <= seen["DISTANCE_SENSOR"].current_distance <= 30  # cm: the body a leg's height up
    assert "frames=0 " not in ap.summary and "json_physics stopped" in ap.summary, ap.summary


def test_a_rangefinder_dropout_reaches_arducopter_as_no_data() -> None:
    """The physics' dropout is a NaN ``rng_1``: ArduCopter's SITL rangefinder then reports no
    data (DISTANCE_SENSOR stops or its status goes bad) rather than 0 m, "too close", which is
    what the negative value the physics used to send read as."""
    binary = _binary()
    from pymavlink import mavutil

    faults = [{"kind": "rangefinder_dropout", "start": 0.0, "end": 1e6}]
    # no arming: ready at its first HEARTBEAT (boot_speedup=None), at ArduCopter's speed-up 4
    with start_arducopter(scenario={"faults": faults}, binary=binary, boot_speedup=None) as ap:
        conn = mavutil.mavlink_connection(ap.mavlink_url, source_system=255)
        try:
            conn.wait_heartbeat(timeout=30)
            conn.mav.command_long_send(1, 1, 511, 0, 132, 100_000, 0, 0, 0, 0, 0)
            conn.mav.command_long_send(1, 1, 511, 0, 1, 200_000, 0, 0, 0, 0, 0)  # SYS_STATUS
            # until 10 readings, or 8 s of wall time (32 s of vehicle time at 4x: DISTANCE_SENSOR,
            # asked at 10 Hz, has stopped) after the first SYS_STATUS; the newest status is judged
            readings, status, deadline = [], None, time.monotonic() + 40
            while time.monotonic() < deadline and (status is None or len(readings) < 10):
                m = conn.recv_match(type=["DISTANCE_SENSOR", "SYS_STATUS"], blocking=True, timeout=1)
                if m is None:
                    continue
                if m.get_type() == "SYS_STATUS":
                    if status is None:
                        deadline = min(deadline, time.monotonic() + 8.0)
                    status = m
                else:
                    readings.append(m.current_distance)
        finally:
            conn.close()
    assert status is not None
    # no reading ever claims the ground is 0 m away, and the rangefinder is reported unhealthy
    rf = mavutil.mavlink.MAV_SYS_STATUS_SENSOR_LASER_POSITION
    assert all(d > 0 for d in readings) or not readings, readings[:10]
    assert status.onboard_control_sensors_present & rf
    assert not status.onboard_control_sensors_health & rf, bin(status.onboard_control_sensors_health)


def test_arducopter_waits_for_a_companion_that_falls_behind() -> None:
    """At speed-up 8 ArduCopter runs ahead of real time while the companion keeps up, and no more
    than the gate's lead (0.25 s of vehicle time, src/slopelander_sitl/json_physics/companion_gate.py) past
    the
    newest time the companion echoed while it reads nothing: a second's stall of the companion is
    not eight seconds of flight it never saw."""
    binary = _binary()
    from slopelander_sitl.rig import Rig

    with pytest.raises(ValueError, match="positive"):
        Rig(autopilot="ardupilot", arducopter=str(binary), arducopter_speedup=0.0)
    with Rig(slope_deg=20.0, autopilot="ardupilot", arducopter=str(binary), arducopter_speedup=8.0) as rig:
        pod = rig.vehicle
        rig.wait(4.0)
        assert rig.link.lockstep is not None  # the rig asks for the echo: ArduCopter is held to it
        stalls = []
        for _ in range(3):
            before = rig.now
            time.sleep(1.0)  # the companion reads nothing
            rig.link.poll()
            stalls.append(rig.now - before)
    assert max(stalls) < 0.25 + 0.05, stalls
    # each stall was ended by the companion's echo, never by the gate's 5 s patience
    assert "holds=" in pod.summary and "give_ups=0" in pod.summary, pod.summary


def _locals_script(n: int) -> str:
    """A script whose main chunk declares ``n`` locals, then says so and ends."""
    decls = "".join(f"local v{i} = {i}\n" for i in range(n - 1))
    return decls + f'local last = {n}\ngcs:send_text(6, "locals probe {n} ran")\nreturn\n'


@pytest.mark.parametrize("n", [100, 101])
def test_arducopters_lua_allows_100_locals_per_function(n: int, tmp_path) -> None:
    """The rule the stand-in mirrors (src/slopelander_sitl/vehicle/lua_limits.py, MAXVARS in ArduPilot's
    libraries/AP_Scripting/lua/src/lparser.c): 100 locals load, the 101st is refused, though
    stock Lua 5.3 (the stand-in's lupa) takes 200."""
    from slopelander_sitl.vehicle.lua_limits import ardupilot_load_error

    binary = _binary()
    script = tmp_path / "probe.lua"
    script.write_text(_locals_script(n))
    # boot_speedup=None: ready at its first HEARTBEAT, as a script runs long before it could arm
    with start_arducopter(binary=binary, script=script, boot_speedup=None) as ap:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and not any(
            "locals probe" in ln or "Lua: Error" in ln for ln in ap.statustexts()
        ):
            time.sleep(0.2)
        texts = ap.statustexts()
    ran = any(f"locals probe {n} ran" in ln for ln in texts)
    refused = any("Lua: Error: ./scripts/probe.lua" in ln and "too man" in ln for ln in texts)
    assert (ran, refused) == ((True, False) if n <= 100 else (False, True)), texts
    assert (ardupilot_load_error(script.read_text()) is None) == ran  # the stand-in agrees
