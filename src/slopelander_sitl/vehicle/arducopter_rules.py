"""ArduCopter's rules that the landing relies on, in one place, so the simulated vehicle answers
and behaves as the real firmware does (never kinder). Each rule names the ArduPilot source file
and function it mirrors (ArduPilot master, 2025; the SITL binary the tests fly is V4.7.0-dev).
Written from reading that source; none of it is copied.

tests/vehicle/test_rules_vs_arducopter.py sends one command sequence
(src/slopelander_sitl/vehicle/ack_sequence.py)
to this vehicle and to real ArduCopter and compares the answers command by command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from slopelander_sitl.vehicle import modes
from slopelander_sitl.vehicle.mavlink_endpoints import mavlink

ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
TEMP_REJECTED = mavlink.MAV_RESULT_TEMPORARILY_REJECTED
DENIED = mavlink.MAV_RESULT_DENIED
UNSUPPORTED = mavlink.MAV_RESULT_UNSUPPORTED
FAILED = mavlink.MAV_RESULT_FAILED

# ---------------------------------------------------------------------------------------------
# (a) arming and disarming
# ---------------------------------------------------------------------------------------------
# libraries/GCS_MAVLink/GCS.h: magic_force_arm_value, magic_force_arm_disarm_value. The two
# magics differ: 21196 in an ARM command is an ordinary arm (all checks run).
FORCE_ARM_MAGIC = 2989
FORCE_DISARM_MAGIC = 21196

# AP_Arming::Method, reduced to what the vehicle distinguishes. method_is_GCS() is true for MAVLINK.
GCS = "GCS"
SCRIPTING = "Script"
LANDED = "Land"
RC = "RC"


def arm_disarm_request(param1: float, param2: float) -> tuple[str, bool]:
    """What a MAV_CMD_COMPONENT_ARM_DISARM asks: ("arm" | "disarm" | "unsupported", checks).

    GCS_MAVLINK::handle_command_component_arm_disarm (libraries/GCS_MAVLink/GCS_Common.cpp):
    param1 exactly 1 arms, with checks unless param2 is 2989; param1 exactly 0 disarms, with
    checks unless param2 is 21196; any other param1 is UNSUPPORTED."""
    if param1 == 1.0:
        return "arm", param2 != FORCE_ARM_MAGIC
    if param1 == 0.0:
        return "disarm", param2 != FORCE_DISARM_MAGIC
    return "unsupported", True


def disarm_refused(method: str, checks: bool, land_complete: bool, manual_throttle: bool) -> bool:
    """AP_Arming_Copter::disarm (ArduCopter/AP_Arming_Copter.cpp): a ground-station disarm
    (method_is_GCS) with checks is refused while the land detector has not fired
    (!ap.land_complete); a rudder disarm also needs a manual-throttle mode or land_complete. The
    on-board script (Method::SCRIPTING), the land detector's own disarm and a forced disarm are
    never refused here. The command handler answers a refusal FAILED."""
    if checks and method == GCS and not land_complete:
        return True
    return method == RC and not manual_throttle and not land_complete


def arming_failure(
    mode: int,
    method: str,
    estop: bool,
    lean_rad: float,
    angle_max_cd: float,
    arming_check: float,
    pilot_climb: bool,
    throttle_stick_up: bool,
    rc_options: int = 32,
) -> str | None:
    """The first reason an arming attempt with checks fails (the STATUSTEXT it sends), or None.

    AP_Arming::arm runs the checks with running_arming_checks set, so check_failed() prefixes
    them "Arm: " (libraries/AP_Arming/AP_Arming.cpp). From AP_Arming_Copter::arm_checks
    (ArduCopter/AP_Arming_Copter.cpp): the mode must allow arming (Mode::allows_arming: GUIDED
    only from the GCS or a script, RTL/LAND/BRAKE never) "<MODE> mode not armable"; with
    ARMING_CHECK not 0, a lean acos(cos roll cos pitch) above ANGLE_MAX is "Leaning", and outside
    GCS/script arming in GUIDED, a pilot climb demand or (manual-throttle modes) throttle above
    zero is "Throttle too high". The motor emergency stop: AP_Arming::estop_checks. Then, for
    every method, GCS in GUIDED too, AP_Arming::rc_arm_checks (libraries/AP_Arming/AP_Arming.cpp,
    from AP_Arming::arm_checks): with RC_OPTIONS bit 5 (ARMING_CHECK_THROTTLE, ArduCopter's
    default 32) the throttle's control input must be zero, the stick at the bottom within its
    dead zone: "Throttle (RC3) is not neutral" (RC input is always present here, as in SITL)."""
    if estop:
        return "Arm: Motors Emergency Stopped"
    armable = modes.ARMABLE if method in (GCS, SCRIPTING) else modes.ARMABLE - {modes.GUIDED}
    if mode not in armable:
        return f"Arm: {modes.NAMES.get(mode, str(mode))} mode not armable"
    if arming_check == 0:
        return None
    if lean_rad > math.radians(angle_max_cd / 100.0):
        return "Arm: Leaning"
    gcs_in_guided = method in (GCS, SCRIPTING) and mode == modes.GUIDED
    if not gcs_in_guided:
        manual = mode in modes.MANUAL_THROTTLE
        if pilot_climb or (manual and throttle_stick_up):
            return "Arm: Throttle too high"
    if rc_options & RC_OPTION_ARMING_CHECK_THROTTLE and throttle_stick_up:
        return "Arm: Throttle (RC3) is not neutral"
    return None


#: RC_OPTIONS bit 5 (RC_Channels::Option::ARMING_CHECK_THROTTLE): arm only with the throttle down
RC_OPTION_ARMING_CHECK_THROTTLE = 32


def rc_override_accepted(source_system: int, gcs_sysid: int = 255) -> bool:
    """GCS_MAVLINK::handle_rc_channels_override (libraries/GCS_MAVLink/GCS_Common.cpp) takes an
    RC_CHANNELS_OVERRIDE only from the ground station's system id (MAV_GCS_SYSID, formerly
    SYSID_MYGCS, default 255): a companion on the vehicle's own id 1 overrides nothing."""
    return source_system == gcs_sysid


# ---------------------------------------------------------------------------------------------
# (b) the land detector
# ---------------------------------------------------------------------------------------------
LAND_CHECK_ANGLE_ERROR_DEG = 30.0  # ArduCopter/land_detector.cpp
LAND_CHECK_LARGE_ANGLE_DEG = 15.0  # LAND_CHECK_LARGE_ANGLE_CD 1500
LAND_CHECK_ACCEL_MOVING = 3.0  # m/s^2
LAND_DETECTOR_TRIGGER_SEC = 1.0  # ArduCopter/config.h
LAND_DETECTOR_MAYBE_TRIGGER_SEC = 0.2
LAND_DETECTOR_ACCEL_MAX = 1.0  # m/s^2, 1 Hz filtered, gravity removed
LAND_DETECTOR_VEL_Z_MAX = 1.0  # m/s
LAND_RANGEFINDER_MIN_ALT_M = 2.0
LAND_ACCEL_FILTER_HZ = 1.0  # Copter::land_accel_ef_filter


@dataclass
class LandInputs:
    """What Copter::update_land_detector reads, once per main loop (SI, world frame, z up)."""

    armed: bool
    throttle_at_lower_limit: bool  # motors->limit.throttle_lower: the mixer's collective at its floor
    angle_target_deg: float  # attitude target lean (the request)
    angle_error_deg: float  # attitude error
    accel_ef: tuple[float, float]  # earth-frame acceleration, gravity removed (x, z)
    climb_rate: float  # m/s, + up
    descent_demanded: bool  # pos_control's desired vertical velocity < 0
    landing_mode: bool  # flightmode->is_landing()
    rangefinder_alt_ok: bool  # a healthy downward rangefinder
    rangefinder_alt_filt_m: float


class LandDetector:
    """Copter::update_land_detector and Copter::update_throttle_mix (ArduCopter/land_detector.cpp).

    Disarmed: landed. Landed stays set until the flight mode takes off (take-off clears it, see
    `takeoff_clears_landed`). In the air, landed after every condition held for
    LAND_DETECTOR_TRIGGER_SEC of main-loop ticks: the motors at their lower limit; the throttle
    mix at its minimum (update_throttle_mix: not set while the request leans over 15 deg, the
    attitude error exceeds 30 deg, the 1 Hz-filtered acceleration exceeds 3 m/s^2, or no descent
    is demanded); no lean request over 15 deg; attitude error at most 30 deg; filtered
    acceleration at most 1 m/s^2; vertical speed under 1 m/s; and, with a healthy rangefinder, its
    filtered height under 2 m. Any condition failing resets the count. Maybe-landed after 0.2 s.
    On a slope the attitude error (the airframe forced to the roof's angle) can keep it from ever
    firing; and once a companion stops demanding descent, so does the throttle mix."""

    def __init__(self, loop_hz: float = 400.0) -> None:
        self.loop_hz = loop_hz
        self.landed = True  # the vehicle boots on the ground, disarmed
        self.count = 0
        self._acc = (0.0, 0.0)

    @property
    def maybe_landed(self) -> bool:
        return self.landed or self.count >= LAND_DETECTOR_MAYBE_TRIGGER_SEC * self.loop_hz

    def set_landed(self, landed: bool) -> None:
        """Copter::set_land_complete: a change resets the count."""
        if landed != self.landed:
            self.count = 0
        self.landed = landed

    def update(self, dt: float, x: LandInputs) -> None:
        w = dt * 2 * math.pi * LAND_ACCEL_FILTER_HZ
        a = w / (1 + w)
        ax, az = self._acc
        self._acc = (ax + a * (x.accel_ef[0] - ax), az + a * (x.accel_ef[1] - az))
        if not x.armed:
            self.set_landed(True)
            return
        if self.landed:
            return
        acc = math.hypot(*self._acc)
        large_request = x.angle_target_deg > LAND_CHECK_LARGE_ANGLE_DEG
        large_error = x.angle_error_deg > LAND_CHECK_ANGLE_ERROR_DEG
        mix_min = not (
            (large_request and not x.landing_mode)
            or large_error
            or acc > LAND_CHECK_ACCEL_MOVING
            or not x.descent_demanded
        )
        ok = (
            x.throttle_at_lower_limit
            and mix_min
            and not large_request
            and not large_error
            and acc <= LAND_DETECTOR_ACCEL_MAX
            and abs(x.climb_rate) < LAND_DETECTOR_VEL_Z_MAX
            and (not x.rangefinder_alt_ok or x.rangefinder_alt_filt_m < LAND_RANGEFINDER_MIN_ALT_M)
        )
        if ok:
            if self.count < LAND_DETECTOR_TRIGGER_SEC * self.loop_hz:
                self.count += 1
            else:
                self.set_landed(True)
        else:
            self.count = 0


def mode_disarms_on_land(mode: int) -> bool:
    """ModeLand/ModeRTL's final descent disarm once landed (ArduCopter/mode_land.cpp
    ModeLand::run -> AP_Arming::disarm(Method::LANDED) when land_complete); GUIDED does not."""
    return mode in (modes.LAND, modes.RTL)


# ---------------------------------------------------------------------------------------------
# (c) take-off (MAV_CMD_NAV_TAKEOFF)
# ---------------------------------------------------------------------------------------------
@dataclass
class Takeoff:
    """A take-off the mode accepted: the target height (m) and its frame."""

    height_m: float
    above_terrain: bool  # True: over the rangefinder's surface; False: above home


def takeoff(
    mode: int,
    armed: bool,
    land_complete: bool,
    height_m: float,
    param3: float,
    height_above_home_m: float,
    rangefinder_healthy: bool,
    rangefinder_alt_m: float,
    rangefinder_max_m: float,
    wpnav_rfnd_use: float,
) -> Takeoff | None:
    """None when ArduCopter refuses the take-off (the command handler answers FAILED).

    GCS_MAVLINK_Copter::handle_MAV_CMD_NAV_TAKEOFF (ArduCopter/GCS_MAVLink_Copter.cpp) passes
    param7 (m) and must_navigate = (param3 == 0) to Mode::do_user_takeoff (ArduCopter/takeoff.cpp):
    refused unless armed, landed (land_complete: no second take-off in the air), the mode has a
    user take-off (GUIDED, LOITER; ALT_HOLD only when param3 != 0; never STABILIZE), and the
    height is above the current height above home. ModeGuided::do_user_takeoff_start
    (ArduCopter/mode_guided.cpp): with a healthy downward rangefinder used for terrain
    (WPNAV_RFND_USE) and a height below RNGFND1_MAX the height is over the surface the
    rangefinder sees, refused when not above its current reading; otherwise above home."""
    if not armed or not land_complete or not math.isfinite(height_m):
        return None
    must_navigate = param3 == 0
    if mode not in (modes.GUIDED, modes.LOITER) and not (mode == modes.ALT_HOLD and not must_navigate):
        return None
    if height_m <= height_above_home_m:
        return None
    if mode == modes.GUIDED and rangefinder_healthy and wpnav_rfnd_use and height_m < rangefinder_max_m:
        if height_m <= rangefinder_alt_m:
            return None
        return Takeoff(height_m, above_terrain=True)
    return Takeoff(height_m, above_terrain=False)


def pilot_takes_off(mode: int, climb_stick: float, throttle_out: float, hover_throttle: float) -> bool:
    """Whether a landed, armed vehicle leaves the ground without a take-off command.
    Mode::_TakeOff::triggered (ArduCopter/takeoff.cpp): ALT_HOLD and LOITER take off when the
    pilot demands a climb. STABILIZE has manual throttle: land_complete clears once the output
    exceeds the non-take-off throttle, half the hover throttle (Copter::update_land_detector,
    get_non_takeoff_throttle). GUIDED never: only MAV_CMD_NAV_TAKEOFF (ModeGuided::run keeps a
    landed vehicle in make_safe_ground_handling whatever target it is sent)."""
    if mode in (modes.ALT_HOLD, modes.LOITER):
        return climb_stick > 0.0
    if mode == modes.STABILIZE:
        return throttle_out > 0.5 * hover_throttle
    return False


# ---------------------------------------------------------------------------------------------
# (d) the rangefinder
# ---------------------------------------------------------------------------------------------
RANGEFINDER_HZ = 20  # ArduCopter/Copter.cpp scheduler table: SCHED_TASK(read_rangefinder, 20, ...)
RANGEFINDER_HEALTH_MAX = 3  # ArduCopter/config.h: good readings in a row before the height is used
RANGEFINDER_FILT_HZ = 0.25  # RANGEFINDER_WPNAV_FILT_HZ: the land detector's filtered height

# RangeFinder::Status (libraries/AP_RangeFinder/AP_RangeFinder.h)
NO_DATA, OUT_OF_RANGE_LOW, OUT_OF_RANGE_HIGH, GOOD = 1, 2, 3, 4


class RangefinderAlt:
    """The downward rangefinder's height as the flight code uses it. Copter::read_rangefinder
    (ArduCopter/sensors.cpp, with AP_SurfaceDistance::update): healthy after
    RANGEFINDER_HEALTH_MAX Good readings in a row (any other status: unhealthy at once); the
    height is the distance times cos(lean); the land detector reads it low-passed at
    RANGEFINDER_WPNAV_FILT_HZ."""

    def __init__(self) -> None:
        self.good_count = 0
        self.alt_m = 0.0
        self.alt_filt_m = 0.0

    @property
    def healthy(self) -> bool:
        return self.good_count >= RANGEFINDER_HEALTH_MAX

    def update(self, distance_m: float, status: int, lean_rad: float, dt: float) -> None:
        if status != GOOD:
            self.good_count = 0
            return
        alt = distance_m * max(0.0, math.cos(lean_rad))
        if self.good_count == 0:
            self.alt_filt_m = alt  # the filter restarts on a new healthy stretch
        self.good_count = min(self.good_count + 1, 100)
        self.alt_m = alt
        w = 2 * math.pi * RANGEFINDER_FILT_HZ * dt
        self.alt_filt_m += w / (1 + w) * (alt - self.alt_filt_m)


def rangefinder_due(tick: int, loop_hz: float) -> bool:
    """True on the main-loop ticks where the 20 Hz rangefinder task runs: the reading the script,
    DISTANCE_SENSOR and the land detector see changes only then."""
    every = max(1, round(loop_hz / RANGEFINDER_HZ))
    return tick % every == 0


def sitl_rangefinder(rng_m: float, min_m: float, max_m: float) -> tuple[float, int]:
    """(distance_m, status) ArduPilot makes of a SITL rangefinder value (the JSON physics' rng_1).

    AP_RangeFinder_SITL::update (libraries/AP_RangeFinder/AP_RangeFinder_SITL.cpp): NaN or inf is
    NoData; anything else is clamped at 0 (a negative value reads 0 m, "too close", not a
    dropout) and classified by AP_RangeFinder_Backend::update_status: above RNGFNDn_MAX
    OutOfRangeHigh, below RNGFNDn_MIN OutOfRangeLow (still reported), else Good."""
    if math.isnan(rng_m) or math.isinf(rng_m):
        return 0.0, NO_DATA
    d = max(0.0, rng_m)
    if d > max_m:
        return d, OUT_OF_RANGE_HIGH
    if d < min_m:
        return d, OUT_OF_RANGE_LOW
    return d, GOOD


# ---------------------------------------------------------------------------------------------
# (e) motors on the ground
# ---------------------------------------------------------------------------------------------
def ground_idle(armed: bool, land_complete: bool, mode: int, estop: bool) -> bool:
    """True when the motors sit at MOT_SPIN_ARM: armed, landed, in a mode with automatic throttle.
    Mode::make_safe_ground_handling (ArduCopter/mode.cpp) spools the motors to GROUND_IDLE and
    relaxes the controllers; AP_MotorsMulticopter::output_logic holds GROUND_IDLE at
    MOT_SPIN_ARM. The emergency stop is SHUT_DOWN (MOT_PWM_MIN), handled before this."""
    return armed and not estop and land_complete and mode not in modes.MANUAL_THROTTLE


def spin_arm_pwm(pwm_min: float, pwm_max: float, spin_arm: float) -> int:
    """AP_MotorsMulticopter::output_to_pwm at GROUND_IDLE: MOT_SPIN_ARM of the PWM range (thrust
    linearisation is not applied at ground idle)."""
    return round(pwm_min + spin_arm * (pwm_max - pwm_min))


# ---------------------------------------------------------------------------------------------
# (f) GUIDED's target time-out
# ---------------------------------------------------------------------------------------------
def guided_target_stale(has_velocity: bool, now_s: float, updated_s: float, guid_timeout_s: float) -> bool:
    """ModeGuided::velaccel_control_run / posvelaccel_control_run (ArduCopter/mode_guided.cpp):
    a target with a velocity part not refreshed for GUID_TIMEOUT s has its velocity and
    acceleration zeroed (the vehicle stops and holds); a position-only target never lapses."""
    return has_velocity and now_s - updated_s > guid_timeout_s


_F = mavlink
LOCAL_TARGET_FRAMES = {
    _F.MAV_FRAME_LOCAL_NED,
    _F.MAV_FRAME_LOCAL_OFFSET_NED,
    _F.MAV_FRAME_BODY_NED,
    _F.MAV_FRAME_BODY_OFFSET_NED,
}
GLOBAL_TARGET_FRAMES = {
    _F.MAV_FRAME_GLOBAL,
    _F.MAV_FRAME_GLOBAL_INT,
    _F.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    _F.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    _F.MAV_FRAME_GLOBAL_TERRAIN_ALT,
    _F.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
}


def local_target_is_offset(frame: int) -> bool:
    """GCS_MAVLINK_Copter::handle_message_set_position_target_local_ned
    (ArduCopter/GCS_MAVLink_Copter.cpp): LOCAL_NED is from the EKF origin; LOCAL_OFFSET_NED,
    BODY_NED and BODY_OFFSET_NED are offsets from the current position (BODY frames rotated by
    yaw first); any other frame stops the vehicle where it is (ModeGuided::init), unanswered.
    MAVProxy's `position x y z` sends BODY_NED."""
    return frame != _F.MAV_FRAME_LOCAL_NED


def global_target_height(frame: int, alt_m: float, home_amsl_m: float, terrain_height_m: float) -> float:
    """Height above home (m) of a SET_POSITION_TARGET_GLOBAL_INT altitude.
    GCS_MAVLINK_Copter::handle_message_set_position_target_global_int: GLOBAL(_INT) is above
    mean sea level, GLOBAL_RELATIVE_ALT(_INT) above home, GLOBAL_TERRAIN_ALT(_INT) above the
    terrain (here the surface the rangefinder sees)."""
    if frame in (_F.MAV_FRAME_GLOBAL, _F.MAV_FRAME_GLOBAL_INT):
        return alt_m - home_amsl_m
    if frame in (_F.MAV_FRAME_GLOBAL_TERRAIN_ALT, _F.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT):
        return terrain_height_m + alt_m
    return alt_m


# ---------------------------------------------------------------------------------------------
# (g) COMMAND_ACK results of the other commands the companion sends
# ---------------------------------------------------------------------------------------------
def set_mode_result(base_mode: float, custom_mode: float, settable: bool) -> int:
    """GCS_MAVLINK::_set_mode_common (libraries/GCS_MAVLink/GCS_Common.cpp): only custom modes
    are accepted (no MAV_MODE_FLAG_CUSTOM_MODE_ENABLED: DENIED); a mode the vehicle cannot enter
    (unknown number, or its checks fail) is FAILED."""
    if not int(base_mode) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return DENIED
    return ACCEPTED if settable else FAILED


def message_interval_result(interval_us: float, loop_hz: float, known_message: bool) -> int:
    """GCS_MAVLINK::handle_command_set_message_interval -> set_message_interval
    (libraries/GCS_MAVLink/GCS_Common.cpp): -1 stops, 0 restores the default; a message the
    vehicle cannot send is DENIED; a request faster than the main loop can send is DENIED with
    "Requested rate for message ID n too fast. Increase SCHED_LOOP_RATE". The boundary is the
    one measured on ArduCopter SITL V4.7.0-dev at SCHED_LOOP_RATE 400 (ack_sequence): 2500 us
    DENIED, 3000, 4000 and 5000 us ACCEPTED, i.e. the interval in whole milliseconds shorter
    than one loop period is refused."""
    if not known_message or interval_us < -1:
        return DENIED
    if interval_us > 0 and int(interval_us // 1000) * 1000 < 1e6 / loop_hz:
        return DENIED
    return ACCEPTED


def do_set_servo_result(channel: float, motor_channels: range = range(1, 5)) -> int:
    """ServoRelayEvents::do_set_servo (libraries/AP_ServoRelayEvents/AP_ServoRelayEvents.cpp):
    refused on a channel whose function is a motor (or any function the autopilot drives);
    the handler (GCS_MAVLINK::handle_do_set_servo) answers a refusal FAILED."""
    return FAILED if int(channel) in motor_channels else ACCEPTED


def unknown_command_result() -> int:
    """GCS_MAVLINK::handle_command_int_packet / handle_command_long_packet default branch."""
    return UNSUPPORTED
