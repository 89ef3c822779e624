"""Each MAVLink link has its own stream rates, as on ArduCopter (one GCS_MAVLINK per serial port,
SRn_ rates and message intervals per channel): a ground station's REQUEST_DATA_STREAM at 4 Hz
on its link does not slow the companion's 200 Hz RAW_IMU on another. MAVProxy re-requests its
4 Hz streams every few seconds; with one set of rates for every link it cut the companion's IMU
to 4 Hz and CHECKS aborted the landing (docs/commands.md's walkthrough)."""

from __future__ import annotations

import itertools
import time

from pymavlink import mavutil

from slopelander_sitl.vehicle.launch import free_port, start_vehicle
from tests.vehicle.conftest import ROUTE_A
from tests.vehicle.flying import M, set_interval


def _rate(conn, kind: str, vehicle_s: float = 2.0) -> float:
    """Messages of ``kind`` per second of vehicle time, counted over ``vehicle_s`` of it."""
    first = last = None
    n = 0
    end = time.monotonic() + 30
    while time.monotonic() < end:
        m = conn.recv_match(type=kind, blocking=True, timeout=1)
        if m is None:
            continue
        t = m.time_usec / 1e6
        first = t if first is None else first
        last, n = t, n + 1
        if last - first >= vehicle_s:
            break
    assert first is not None and last is not None and last > first, f"no {kind}"
    return (n - 1) / (last - first)


def test_a_ground_stations_stream_request_leaves_the_companions_rates_and_answers_alone():
    gcs_port = free_port()
    # at 2x real time: the rates are counted on the vehicle's clock
    gcs_end = f"tcpin:127.0.0.1:{gcs_port}"
    v = start_vehicle(params=ROUTE_A, no_script=True, speed=2.0, extra_endpoints=[gcs_end])
    companion = mavutil.mavlink_connection(v.mavlink_url, source_system=255, source_component=191)
    gcs = mavutil.mavlink_connection(f"tcp:127.0.0.1:{gcs_port}", source_system=255, source_component=190)
    try:
        assert companion.wait_heartbeat(timeout=20) and gcs.wait_heartbeat(timeout=20)
        gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
        while gcs.recv_match(blocking=False) is not None:  # what came before the command
            pass
        assert set_interval(companion, M.MAVLINK_MSG_ID_RAW_IMU, 200).result == M.MAV_RESULT_ACCEPTED
        # the command's answer goes to the link that asked, as ArduCopter's: MAVProxy on its own
        # link does not show the companion's COMMAND_ACKs
        gcs_acks = [gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=1.5)]
        gcs.mav.request_data_stream_send(1, 1, M.MAV_DATA_STREAM_ALL, 4, 1)  # what MAVProxy sends
        time.sleep(0.5)
        companion_hz, gcs_hz = _rate(companion, "RAW_IMU"), _rate(gcs, "RAW_IMU")
        # a link's own sequence numbers: messages for the other link leave no gaps in it
        seqs = [gcs.recv_match(blocking=True, timeout=1) for _ in range(30)]
    finally:
        companion.close()
        gcs.close()
        v.stop()
    assert gcs_acks == [None]
    assert companion_hz > 150, companion_hz
    assert 3 < gcs_hz < 6, gcs_hz
    got = [m.get_seq() for m in seqs if m is not None]
    gaps = [b for a, b in itertools.pairwise(got) if b != (a + 1) % 256]
    assert len(got) == 30 and gaps == [], got
