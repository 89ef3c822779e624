"""MAVLink messages the vehicle answers: commands with COMMAND_ACK, modes, parameters,
guided targets, stream intervals, TIMESYNC (also the lock-step echo) and RC overrides."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

from slopelander_sitl.vehicle import arducopter_rules as rules
from slopelander_sitl.vehicle import modes
from slopelander_sitl.vehicle.flight_control import Target
from slopelander_sitl.vehicle.mavlink_endpoints import mavlink

if TYPE_CHECKING:
    from slopelander_sitl.vehicle.vehicle import Vehicle

ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
TEMP_REJECTED = mavlink.MAV_RESULT_TEMPORARILY_REJECTED
DENIED = mavlink.MAV_RESULT_DENIED
UNSUPPORTED = mavlink.MAV_RESULT_UNSUPPORTED
FAILED = mavlink.MAV_RESULT_FAILED
AUX_MOTOR_ESTOP = 31
EARTH_RADIUS_M = 6378137.0  # WGS-84 equatorial, as ArduPilot's Location offsets
#: SET_POSITION_TARGET_* type_mask: the yaw field is ignored
YAW_IGNORE = 0x400


def handle(v: Vehicle, chan: int, m) -> None:
    kind = m.get_type()
    fn = _HANDLERS.get(kind)
    if fn is None:
        return
    target = getattr(m, "target_system", None)
    if target not in (None, 0, v.links.sysid) and kind != "TIMESYNC":
        return
    fn(v, chan, m)


def _command_long(v: Vehicle, chan: int, m) -> None:
    cmd = m.command
    if v.host is not None and v.host.blocks_command(cmd):
        v.host.deliver(m, chan)
        return
    p = (m.param1, m.param2, m.param3, m.param4, m.param5, m.param6, m.param7)
    fn = _COMMANDS.get(cmd)
    if fn is None:
        v.ack(cmd, rules.unknown_command_result(), chan=chan)
        return
    if any(math.isnan(x) for x in p[:2]) and cmd != mavlink.MAV_CMD_NAV_TAKEOFF:
        v.ack(cmd, DENIED, chan=chan)
        return
    v.ack(cmd, _LINK_COMMANDS[cmd](v, p, chan) if cmd in _LINK_COMMANDS else fn(v, p), chan=chan)


def _arm(v: Vehicle, p) -> int:
    what, checks = rules.arm_disarm_request(p[0], p[1])
    if what == "arm":
        return ACCEPTED if v.arm(force=not checks) else FAILED
    if what == "disarm":
        return ACCEPTED if v.disarm(rules.GCS, checks=checks) else FAILED
    return UNSUPPORTED


def _do_set_mode(v: Vehicle, p) -> int:
    flag_ok = bool(int(p[0]) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
    return rules.set_mode_result(p[0], p[1], flag_ok and _enter_mode(v, p[1]))


def _enter_mode(v: Vehicle, mode: float) -> bool:
    if int(mode) not in modes.NAMES:
        v.statustext(f"No such mode {int(mode)}", mavlink.MAV_SEVERITY_WARNING)  # Copter::set_mode
        return False
    return v.set_mode(int(mode))


def _takeoff(v: Vehicle, p) -> int:
    return ACCEPTED if v.takeoff(p[6], p[2]) else FAILED


def _do_set_servo(v: Vehicle, p) -> int:
    # the stand-in drives no servo outputs besides the four motors; a free channel is accepted
    result = rules.do_set_servo_result(p[0])
    if result != ACCEPTED:
        v.statustext(f"ServoRelayEvent: Channel {int(p[0])} is already in use", mavlink.MAV_SEVERITY_INFO)
    return result


def _aux(v: Vehicle, p) -> int:
    if int(p[0]) != AUX_MOTOR_ESTOP:
        return UNSUPPORTED
    if int(p[1]) not in (0, 1, 2):
        return DENIED
    on = int(p[1]) == 2
    if on != v.estop:
        v.estop = on
        v.statustext("Motor emergency stop " + ("on" if on else "off"), mavlink.MAV_SEVERITY_WARNING)
    return ACCEPTED


def _interval(v: Vehicle, p, chan: int = 0) -> int:
    """MAV_CMD_SET_MESSAGE_INTERVAL: on the link it came from only (GCS_MAVLINK::set_message_interval)."""
    msgid, interval = int(p[0]), p[1]
    result = rules.message_interval_result(interval, v.params["SCHED_LOOP_RATE"], msgid in v.streams.SENDERS)
    if result != ACCEPTED:
        if msgid in v.streams.SENDERS:
            text = f"Requested rate for message ID {msgid} too fast. Increase SCHED_LOOP_RATE"
            v.statustext(text, mavlink.MAV_SEVERITY_WARNING)
        return result
    seconds = None if interval == 0 else (-1.0 if interval < 0 else interval / 1e6)
    v.streams.set_interval(msgid, seconds, chan)
    return ACCEPTED


def _request_message(v: Vehicle, p, chan: int | None = None) -> int:
    """MAV_CMD_REQUEST_MESSAGE: answered on the link that asked."""
    msgid = int(p[0])
    if msgid == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
        _send_version(v)
        return ACCEPTED
    if msgid in v.streams.SENDERS:
        v.streams.send_now(v, msgid, chan)
        return ACCEPTED
    return DENIED


def _capabilities(v: Vehicle, p) -> int:
    _send_version(v)
    return ACCEPTED


def _nav_land(v: Vehicle, p) -> int:
    return ACCEPTED if v.set_mode(modes.LAND) else FAILED


def _send_version(v: Vehicle) -> None:
    caps = (
        mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
        | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
        | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
        | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    )
    ver = (4 << 24) | (6 << 16) | (0 << 8) | 255  # 4.6.0 official
    v.links.send(
        mavlink.MAVLink_autopilot_version_message(
            caps, ver, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0, [0] * 18
        )
    )


def _set_mode_msg(v: Vehicle, chan: int, m) -> None:
    flag_ok = bool(m.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
    ok = flag_ok and _enter_mode(v, m.custom_mode)
    v.ack(mavlink.MAVLINK_MSG_ID_SET_MODE, rules.set_mode_result(m.base_mode, m.custom_mode, ok), chan=chan)


def _param_value(v: Vehicle, name: str) -> None:
    v.links.send(
        mavlink.MAVLink_param_value_message(
            name.encode(),
            float(v.params[name]),
            mavlink.MAV_PARAM_TYPE_REAL32,
            len(v.params),
            v.params.index(name),
        )
    )


def _param_list(v: Vehicle, chan: int, m) -> None:
    for name in v.params.names:
        _param_value(v, name)


def _param_read(v: Vehicle, chan: int, m) -> None:
    name = _pname(m.param_id)
    if m.param_index >= 0 and m.param_index < len(v.params):
        name = v.params.names[m.param_index]
    if name in v.params:
        _param_value(v, name)


def _param_set(v: Vehicle, chan: int, m) -> None:
    name = _pname(m.param_id)
    if name not in v.params:
        v.statustext(f"Unknown parameter {name}", mavlink.MAV_SEVERITY_WARNING)
        return
    v.params.set(name, float(m.param_value))
    _param_value(v, name)  # ArduPilot answers with the value it now holds


def _pname(raw) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode(errors="replace")
    return raw.rstrip("\0").upper()


def _position_target(v: Vehicle, chan: int, m) -> None:
    """SET_POSITION_TARGET_LOCAL_NED in GUIDED (arducopter_rules.local_target_is_offset): the
    planar vehicle flies to the point of its heading's line nearest the target (an offset across
    the heading is not flown). A yaw (type_mask bit 10 clear) turns it to that heading: from north
    in LOCAL_NED and LOCAL_OFFSET_NED, from its own heading in the BODY frames (ModeGuided's
    set_yaw_state); a target without a yaw holds the heading it has."""
    if v.mode != modes.GUIDED:
        return
    b = v._world_body()
    if m.coordinate_frame not in rules.LOCAL_TARGET_FRAMES:
        _hold_here(v, b)
        return
    w = v.world
    c, s = w._dir()
    body = m.coordinate_frame in (mavlink.MAV_FRAME_BODY_NED, mavlink.MAV_FRAME_BODY_OFFSET_NED)
    v_along = m.vx if body else m.vx * c + m.vy * s
    if body:
        along, up = b.x + m.x, b.z - m.z  # body x is the heading
    elif rules.local_target_is_offset(m.coordinate_frame):
        along, up = b.x + m.x * c + m.y * s, b.z - m.z
    else:
        along, up = w.slice_x(v.home_ne[0] + m.x, v.home_ne[1] + m.y), v.home[1] - m.z
    if _set_guided_target(v, m.type_mask, (m.x, m.y, m.z, m.vx, m.vy, m.vz), along, up, v_along, -m.vz):
        _set_heading(v, m.type_mask, m.yaw, body)
        if not body and not rules.local_target_is_offset(m.coordinate_frame) and v.target.x is not None:
            v.target_ne = (v.target, v.home_ne[0] + m.x, v.home_ne[1] + m.y)


def _set_heading(v: Vehicle, mask: int, yaw: float, relative: bool) -> None:
    if mask & YAW_IGNORE or not math.isfinite(yaw):
        v.heading_target = None
    else:
        v.heading_target = (math.degrees(yaw) + (v.world.heading_deg if relative else 0.0)) % 360.0


def _position_target_global(v: Vehicle, chan: int, m) -> None:
    """SET_POSITION_TARGET_GLOBAL_INT in GUIDED: latitude and longitude to north and east of home
    on the flat earth around home, then as a local target."""
    if v.mode != modes.GUIDED:
        return
    b = v._world_body()
    if m.coordinate_frame not in rules.GLOBAL_TARGET_FRAMES:
        _hold_here(v, b)
        return
    hz = v.home[1]
    lat0 = v.params["SIM_OPOS_LAT"]
    north = v.home_ne[0] + math.radians(m.lat_int / 1e7 - lat0) * EARTH_RADIUS_M
    east_radius = EARTH_RADIUS_M * math.cos(math.radians(lat0))
    east = v.home_ne[1] + math.radians(m.lon_int / 1e7 - v.params["SIM_OPOS_LNG"]) * east_radius
    terrain = (b.z - v.range_alt.alt_m - hz) if v.range_alt.healthy else 0.0
    up = hz + rules.global_target_height(m.coordinate_frame, m.alt, v.params["SIM_OPOS_ALT"], terrain)
    vals = (m.lat_int, m.lon_int, m.alt, m.vx, m.vy, m.vz)
    c, s = v.world._dir()
    if _set_guided_target(v, m.type_mask, vals, v.world.slice_x(north, east), up, m.vx * c + m.vy * s, -m.vz):
        _set_heading(v, m.type_mask, m.yaw, False)
        if v.target.x is not None:
            v.target_ne = (v.target, north, east)


def _hold_here(v: Vehicle, b) -> None:
    v.target = Target(x=b.x, z=b.z)
    v.target_is_velocity = False


def _set_guided_target(v: Vehicle, mask: int, vals, north: float, up: float, vn: float, vup: float) -> bool:
    """Set the target (``north``: along the heading's line); False: not finite, ignored."""
    use_pos = mask & 7 != 7
    use_vel = mask & 56 != 56
    if not all(math.isfinite(x) for x in vals):
        return False
    t = Target()
    if use_pos:
        t.x, t.z = north, up
    if use_vel:
        t.vx, t.vz = vn, vup
        if not use_pos:
            t.x = t.z = None
    v.target = t
    v.target_is_velocity = use_vel  # a velocity part lapses after GUID_TIMEOUT (rules (f))
    v.target_time = v.t
    return True


FTP_NAK, FTP_ERR_FILE_NOT_FOUND = 129, 10


def _ftp(v: Vehicle, chan: int, m) -> None:
    """MAVLink FTP: the stand-in serves no files. Every request is answered at once with a NAK
    "file not found" (what ArduPilot's FTP server answers for a path it lacks), so a ground
    station's parameter download by FTP (MAVProxy's @PARAM/param.pck) falls back to
    PARAM_REQUEST_LIST instead of waiting out its time-outs."""
    req = bytes(m.payload)
    seq, session, opcode = req[0] | req[1] << 8, req[2], req[3]
    reply = bytes([(seq + 1) & 0xFF, ((seq + 1) >> 8) & 0xFF, session, FTP_NAK, 1, opcode, 0, 0])
    reply += bytes(4) + bytes([FTP_ERR_FILE_NOT_FOUND])
    payload = list(reply.ljust(251, b"\0"))
    v.links.send(
        mavlink.MAVLink_file_transfer_protocol_message(0, m.get_srcSystem(), m.get_srcComponent(), payload)
    )


def _timesync(v: Vehicle, chan: int, m) -> None:
    now_ns = int(v.t * 1e9)
    if m.tc1 == 0:
        v.links.send(mavlink.MAVLink_timesync_message(now_ns, m.ts1))
    else:
        # a companion's echo: ts1 is the newest vehicle time it has seen (ns)
        echo = m.ts1 / 1e9
        if v.echo_t is None or echo >= v.echo_t:
            v.echo_t = echo
            v.echo_wall = time.monotonic()


def _data_stream(v: Vehicle, chan: int, m) -> None:
    """REQUEST_DATA_STREAM: the rates of the link it came from (GCS_MAVLINK::handle_request_data_stream)."""
    v.streams.request_data_stream(m.req_stream_id, m.req_message_rate if m.start_stop else 0, chan)


def _rc_override(v: Vehicle, chan: int, m) -> None:
    if not rules.rc_override_accepted(m.get_srcSystem(), int(v.params["MAV_GCS_SYSID"])):
        return
    for i in range(1, 9):
        pwm = getattr(m, f"chan{i}_raw")
        if pwm not in (0, 65535):
            v.rc_override[i] = (int(pwm), v.t)
        elif pwm == 0:
            v.rc_override.pop(i, None)


_COMMANDS = {
    mavlink.MAV_CMD_COMPONENT_ARM_DISARM: _arm,
    mavlink.MAV_CMD_DO_SET_MODE: _do_set_mode,
    mavlink.MAV_CMD_NAV_TAKEOFF: _takeoff,
    mavlink.MAV_CMD_NAV_LAND: _nav_land,
    mavlink.MAV_CMD_DO_AUX_FUNCTION: _aux,
    mavlink.MAV_CMD_DO_SET_SERVO: _do_set_servo,
    mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: _interval,
    mavlink.MAV_CMD_REQUEST_MESSAGE: _request_message,
    mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: _capabilities,
}

#: commands that act on the link they came from
_LINK_COMMANDS = {
    mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: _interval,
    mavlink.MAV_CMD_REQUEST_MESSAGE: _request_message,
}

_HANDLERS = {
    "COMMAND_LONG": _command_long,
    "SET_MODE": _set_mode_msg,
    "PARAM_REQUEST_LIST": _param_list,
    "PARAM_REQUEST_READ": _param_read,
    "PARAM_SET": _param_set,
    "SET_POSITION_TARGET_LOCAL_NED": _position_target,
    "SET_POSITION_TARGET_GLOBAL_INT": _position_target_global,
    "FILE_TRANSFER_PROTOCOL": _ftp,
    "TIMESYNC": _timesync,
    "REQUEST_DATA_STREAM": _data_stream,
    "RC_CHANNELS_OVERRIDE": _rc_override,
}
