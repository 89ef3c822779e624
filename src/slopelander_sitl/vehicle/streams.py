"""Telemetry streams: which messages go out at what interval (vehicle time) on each link, set by
SET_MESSAGE_INTERVAL or REQUEST_DATA_STREAM received on that link, and how each is built from the
vehicle's state. Each link has its own rates, as each of ArduCopter's GCS_MAVLINK channels has
(its SRn_ stream rates and message intervals): a ground station asking for 4 Hz on its link
does not slow the 200 Hz IMU a companion asked for on another."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, ClassVar

from slopelander_sitl.vehicle import modes
from slopelander_sitl.vehicle.mavlink_endpoints import mavlink

if TYPE_CHECKING:
    from slopelander_sitl.vehicle.vehicle import Vehicle

M = mavlink
EARTH_RADIUS_M = 6378137.0
DEFAULT_INTERVALS = {  # s; what a client sees before asking for anything
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    M.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: 1.0,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 0.1,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 0.1,
}
# REQUEST_DATA_STREAM groups (ArduPilot's stream sets, reduced to what this vehicle sends)
STREAM_GROUPS = {
    M.MAV_DATA_STREAM_RAW_SENSORS: [M.MAVLINK_MSG_ID_RAW_IMU],
    M.MAV_DATA_STREAM_EXTENDED_STATUS: [M.MAVLINK_MSG_ID_SYS_STATUS],
    M.MAV_DATA_STREAM_RC_CHANNELS: [M.MAVLINK_MSG_ID_RC_CHANNELS, M.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW],
    M.MAV_DATA_STREAM_POSITION: [M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT],
    M.MAV_DATA_STREAM_EXTRA1: [M.MAVLINK_MSG_ID_ATTITUDE],
    M.MAV_DATA_STREAM_EXTRA3: [M.MAVLINK_MSG_ID_DISTANCE_SENSOR, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE],
}


def _heartbeat(v: Vehicle):
    base = (
        M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        | M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    )
    if v.mode in modes.POSITION_MODES:
        base |= M.MAV_MODE_FLAG_GUIDED_ENABLED
    if v.armed:
        base |= M.MAV_MODE_FLAG_SAFETY_ARMED
    status = M.MAV_STATE_ACTIVE if v.armed else M.MAV_STATE_STANDBY
    return M.MAVLink_heartbeat_message(
        M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, base, v.mode, status, 3
    )


def _sys_status(v: Vehicle):
    sensors = (
        M.MAV_SYS_STATUS_SENSOR_3D_GYRO
        | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL
        | M.MAV_SYS_STATUS_SENSOR_LASER_POSITION
    )
    # GCS_MAVLINK::update_sensor_status_flags: the geofence's health bit is set whenever the
    # fence has not failed, even with no fence (a ground station reads a clear bit as a breach)
    health = sensors | M.MAV_SYS_STATUS_GEOFENCE
    return M.MAVLink_sys_status_message(sensors, sensors, health, 200, 16000, 500, 90, 0, 0, 0, 0, 0, 0)


def _yaw(v: Vehicle) -> float:
    """The heading as ATTITUDE's yaw (rad, -pi..pi)."""
    return math.radians((v.world.heading_deg + 180.0) % 360.0 - 180.0)


def _attitude(v: Vehicle):
    b = v.stepper.body()
    return M.MAVLink_attitude_message(int(v.t * 1000), 0.0, b.pitch, _yaw(v), 0.0, b.pitch_rate, v.yaw_rate)


def _ne(v: Vehicle, b) -> tuple[float, float, float, float]:
    """(north, east) from home and (v north, v east) of the body ``b`` along the heading's slice."""
    w = v.world
    n, e = w.ne(b.x)
    c, s = w._dir()
    return n - v.home_ne[0], e - v.home_ne[1], b.vx * c, b.vx * s


def _local_position(v: Vehicle):
    b = v._world_body()
    n, e, vn, ve = _ne(v, b)
    return M.MAVLink_local_position_ned_message(int(v.t * 1000), n, e, -(b.z - v.home[1]), vn, ve, -b.vz)


def _global_position(v: Vehicle):
    """GLOBAL_POSITION_INT on the flat earth around the origin (SIM_OPOS_*); the relative altitude
    above home, which arming resets (``Vehicle.arm_home``), as ArduCopter's ``relative_alt``."""
    b = v._world_body()
    n, e, vn, ve = _ne(v, b)
    lat0 = v.params["SIM_OPOS_LAT"]
    lat = lat0 + math.degrees(n / EARTH_RADIUS_M)
    lng = v.params["SIM_OPOS_LNG"] + math.degrees(e / (EARTH_RADIUS_M * math.cos(math.radians(lat0))))
    rel = b.z - v.arm_home[1]
    return M.MAVLink_global_position_int_message(
        int(v.t * 1000),
        round(lat * 1e7),
        round(lng * 1e7),
        round((v.params["SIM_OPOS_ALT"] + b.z - v.home[1]) * 1000),
        round(rel * 1000),
        round(vn * 100),
        round(ve * 100),
        round(-b.vz * 100),
        round(v.world.heading_deg % 360.0 * 100) % 36000,
    )


def _highres_imu(v: Vehicle):
    a, g = v.imu.accel, v.imu.gyro
    return M.MAVLink_highres_imu_message(
        int(v.t * 1e6), a[0], a[1], a[2], g[0], g[1], g[2], 0.2, 0.0, 0.4, 1013.25, 0.0, 0.0, 25.0, 0x3F, 0
    )


def _raw_imu(v: Vehicle):
    a, g = v.imu.accel, v.imu.gyro

    def mg(x: float) -> int:
        return max(-32768, min(32767, round(x / 9.80665 * 1000)))

    def mrad(x: float) -> int:
        return max(-32768, min(32767, round(x * 1000)))

    return M.MAVLink_raw_imu_message(
        int(v.t * 1e6), mg(a[0]), mg(a[1]), mg(a[2]), mrad(g[0]), mrad(g[1]), mrad(g[2]), 0, 0, 0, 0, 2500
    )


def _distance(v: Vehicle):
    """None while the sensor has no data: ArduCopter sends no DISTANCE_SENSOR then
    (GCS_MAVLINK::send_distance_sensor returns unless ``has_data()``, status neither NotConnected
    nor NoData; libraries/GCS_MAVLink/GCS_Common.cpp). A companion sees the range age."""
    r = v.range
    if r.status in (0, 1):
        return None
    d = r.distance_m if math.isfinite(r.distance_m) else v.range_max
    cm = max(0, min(65535, round(d * 100)))
    # MAVLink signal_quality: 0 unknown, 1 invalid, 2..100 (ArduPilot maps its pct this way)
    q = 0 if r.quality_pct < 0 else (1 if r.quality_pct == 0 else max(2, r.quality_pct))
    return M.MAVLink_distance_sensor_message(
        int(v.t * 1000),
        round(v.range_min * 100),
        round(v.range_max * 100),
        cm,
        M.MAV_DISTANCE_SENSOR_LASER,
        1,
        M.MAV_SENSOR_ROTATION_PITCH_270,
        0,
        0.0,
        0.0,
        [0.0] * 4,
        q,
    )


def _rc_channels(v: Vehicle):
    ch = [v.rc(i) for i in range(1, 17)]
    return M.MAVLink_rc_channels_message(int(v.t * 1000), 16, *ch, 0, 0, 255)


def _servo_output(v: Vehicle):
    out = list(v.out_pwm) + [0] * 12
    return M.MAVLink_servo_output_raw_message(int(v.t * 1e6) & 0xFFFFFFFF, 0, *out)


def _ext_state(v: Vehicle):
    if not v.armed or v.land.landed:
        landed = M.MAV_LANDED_STATE_ON_GROUND
    elif v.mode in (modes.LAND, modes.RTL) or (v.target.vz < 0 and v.target.z is None):
        landed = M.MAV_LANDED_STATE_LANDING
    else:
        landed = M.MAV_LANDED_STATE_IN_AIR
    return M.MAVLink_extended_sys_state_message(M.MAV_VTOL_STATE_MC, landed)


def system_time(v: Vehicle):
    """SYSTEM_TIME now (also sent by a lock-stepped vehicle when it starts to wait)."""
    return M.MAVLink_system_time_message(int(time.time() * 1e6), int(v.t * 1000))


class Streams:
    SENDERS: ClassVar[dict] = {
        M.MAVLINK_MSG_ID_HEARTBEAT: _heartbeat,
        M.MAVLINK_MSG_ID_SYS_STATUS: _sys_status,
        M.MAVLINK_MSG_ID_ATTITUDE: _attitude,
        M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: _local_position,
        M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: _global_position,
        M.MAVLINK_MSG_ID_HIGHRES_IMU: _highres_imu,
        M.MAVLINK_MSG_ID_RAW_IMU: _raw_imu,
        M.MAVLINK_MSG_ID_DISTANCE_SENSOR: _distance,
        M.MAVLINK_MSG_ID_RC_CHANNELS: _rc_channels,
        M.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW: _servo_output,
        M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: _ext_state,
        M.MAVLINK_MSG_ID_SYSTEM_TIME: system_time,
    }

    def __init__(self, channels: int = 1) -> None:
        self.interval: list[dict[int, float]] = [dict(DEFAULT_INTERVALS) for _ in range(max(1, channels))]
        self.next_t: list[dict[int, float]] = [{} for _ in self.interval]

    def set_interval(self, msgid: int, seconds: float | None, chan: int = 0) -> None:
        """On link ``chan``: None, back to the default; negative, off."""
        interval, next_t = self.interval[chan], self.next_t[chan]
        if seconds is None:
            interval.pop(msgid, None)
            if msgid in DEFAULT_INTERVALS:
                interval[msgid] = DEFAULT_INTERVALS[msgid]
        elif seconds < 0:
            interval.pop(msgid, None)
        else:
            interval[msgid] = seconds
        next_t.pop(msgid, None)

    def request_data_stream(self, stream_id: int, rate_hz: int, chan: int = 0) -> None:
        groups = (
            STREAM_GROUPS.values()
            if stream_id == M.MAV_DATA_STREAM_ALL
            else [STREAM_GROUPS.get(stream_id, [])]
        )
        for ids in groups:
            for msgid in ids:
                self.set_interval(msgid, 1.0 / min(rate_hz, 200) if rate_hz > 0 else -1.0, chan)

    def send_now(self, v: Vehicle, msgid: int, chan: int | None = None) -> None:
        """One message now, on link ``chan`` (the one that asked; None: every link)."""
        msg = self.SENDERS[msgid](v)
        if msg is not None:
            v.links.send(msg, chan)

    def send_due(self, v: Vehicle) -> None:
        now = v.t
        built: dict[int, object] = {}  # a message due on several links is built once
        for chan, (intervals, next_t) in enumerate(zip(self.interval, self.next_t, strict=True)):
            for msgid, iv in intervals.items():
                nt = next_t.get(msgid, now)
                if now + 1e-9 >= nt:
                    if msgid not in built:
                        built[msgid] = self.SENDERS[msgid](v)
                    msg = built[msgid]
                    if msg is not None:  # nothing to say (a sensor without data)
                        v.links.send(msg, chan)
                    nt = nt + iv if now - nt < iv else now + iv
                    next_t[msgid] = nt
