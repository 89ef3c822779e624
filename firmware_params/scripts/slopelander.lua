-- slopelander on-board script: motor stop and reverse thrust for fast landings on slopes.
--
-- Output route A: a stock quad frame (FRAME_CLASS 1) with analog-PWM bidirectional ("3D") ESCs.
-- 1500 us is stopped, 2000 full forward, 1000 full reverse. MOT_PWM_MIN 1525 keeps the stock
-- mixer and its tuning on the forward half only; this script alone drives an output to 1500
-- (stop) or below (reverse), through an override it refreshes every update. Route B (scripted
-- 6DoF frame with DShot) was not chosen: its mixer may command a motor below zero in flight for
-- attitude control, which a real ESC answers with a ~250 ms stop-and-restart; and upstream
-- ArduCopter does not support reversible motors on copter frames.
--
-- The companion decides; this script only does what cannot wait for a MAVLink round trip, and
-- keeps a landed vehicle's motors stopped until it is disarmed or released level for take-off.
-- Contract (commands, states, validity rules): docs/onboard-script.md in slopelander.

-- ArduPilot's Lua allows 100 local variables per function (MAXVARS in
-- libraries/AP_Scripting/lua/src/lparser.c; stock Lua: 200): constants of one kind share a table.
local VERSION = 10 -- 2: a refresh during RVT sets its duration (the companion ends it on evidence)
-- 3: the reflex arm's param 7 ramps the reverse thrust down over that many ms when it ends
-- 4: param 7 of every command is a request number, echoed in COMMAND_ACK.result_param2; the ramp
--    and the descent rate move to a SETUP request (reflex action 3) sent before ARM; new reflex
--    actions END_REVERSE 2, TAKEOFF_RELEASE 4 (only level), DISARM 5 (only held and still); the
--    cut counts distinct rangefinder samples (the driver's reading time), 2 of them; reverse
--    thrust only with the range at or below the cut height; RVT and HOLD give the motors back
--    when the range says the vehicle left the roof; the missed-impact bound follows the cut height
--    and the descent rate; an abort or release during CUT/RVT/HOLD is refused; a silent
--    companion's HOLD disarms only while still; the impact threshold is at least 2 g.
-- 5: an error in the update no longer stops the script: it reports FAULT (30) or, from the cut
--    on, FAULT_HELD (31: the motors held stopped, the reverse thrust ramped down, disarmed once
--    still) with the error; an ARMED reflex whose validity lapses stops the descent itself and
--    climbs (CLIMB, 14); a disarm needs the vehicle still for STILL.MS, not one sample; CUT's
--    override outlasts a stalled scripting thread as RVT's and HOLD's do.
-- 6: a cut with no impact by the bound whose vehicle still falls freely (a low reading that
--    lasted: the cut was made high) keeps the cut for up to MS.FALL_WAIT and reverses on the
--    impact, instead of HOLD in the air.
-- 7: ARMED cuts on the descent reckoned from the last trusted reading when no reading has agreed
--    with it for RECKON.AFTER_MS within RECKON.WINDOW_M of the cut height (a dropout, a spike).
-- 8: a reading that stopped moving (RECKON.STILL_M) is silence for the reckoning (a stuck sensor);
--    the impact is a push up the body (IMPACT.UP): an accelerometer reading down is not the roof;
--    a glitch against a chain at the cut height does not hide the impact (RECKON.ground); a false
--    cut is released only while the vehicle falls freely.
-- 9: an ARMED reflex that lapses within CLIMB_UP.GRACE_M of its cut height while descending keeps
--    its cut 400 ms more before it climbs.
-- 10: that band grows with the square of the descent speed over CLIMB_UP.AT_MPS, and the cut is
--    kept as long as braking to rest across it takes.
local CMD_ACTUATOR = 31010 -- MAV_CMD_USER_1
local CMD_REFLEX = 31011 -- MAV_CMD_USER_2
local ACT = { RELEASE = 0, STOP = 1, REVERSE = 2 }
local RFX = { ABORT = 0, ARM = 1, END_REVERSE = 2, SETUP = 3, TAKEOFF_RELEASE = 4, DISARM = 5 }
local REQUEST_MAX = 16777215 -- request numbers: whole numbers a float32 parameter holds exactly
local MSG = { COMMAND_LONG = 76, COMMAND_ACK = 77 }
local ACCEPTED, TEMP_REJECTED, DENIED = 0, 1, 2
local SEV = { WARNING = 4, INFO = 6 }
local DOWN = 25 -- rangefinder orientation: pitch 270, facing down
local RF = { LOW = 2, HIGH = 3, GOOD = 4 } -- RangeFinder::Status OutOfRangeLow, OutOfRangeHigh, Good
local MOTORS = { 0, 1, 2, 3 } -- SERVO1..4, 0-based channel index
local PWM_STOP = 1500
local OVERRIDE_MS = 30 -- each override lapses this soon unless refreshed
-- From the cut on (CUT, RVT, HOLD, FAULT_HELD) the override outlasts a stalled scripting thread.
-- ArduPilot counts an override's timeout in main-loop ticks (SRV_Channels::
-- set_output_pwm_chan_timeout), not in the script's own runs: a scripting thread starved for more
-- than OVERRIDE_MS hands the outputs back to the mixer. On a steep roof an armed mixer fights the
-- tilt at full forward thrust (seen on ArduCopter SITL at 55 deg: 40 ms at 1600-1976 us, twice in
-- 25 s); in CUT it is a mixer demanding climb for a vehicle falling onto the roof. Stopped or
-- reversed motors are the safe side of a stall once the motors are cut, so they hold this long;
-- leaving these states clears them at once. In the air (STOP, REVERSE) 30 ms gives the vehicle
-- back quickly.
local HELD_OVERRIDE_MS = 250
-- update periods: while anything is active, otherwise (command latency); SL_STATE at 5 Hz, SL_VER
-- at 1 Hz, a fault's STATUSTEXT every 5 s
local MS = { FAST = 2, IDLE = 10, ANNOUNCE = 200, VERSION = 1000, FAULT_SAY = 5000, FALL_WAIT = 500 }
local GRAVITY = 9.80665
-- The filtered accelerometer reads the thrust over the mass, ~1 g, in the steady descent at the
-- cut, and falls toward 0 g as the thrust decays: an impact threshold must lie well above 1 g.
-- 2 g leaves a full g for the controller's corrections and the vibration left after the filter.
local IMPACT = { MIN = 2 * GRAVITY }
-- After the cut the specific force only falls (the thrust decays, the vehicle falls freely) until
-- something pushes on the vehicle: the threshold counts from the lowest reading since the cut,
-- threshold - 1 g above it, never more than the threshold itself. A soft first contact (an uphill
-- leg near the horizontal slips at a small foot force) lifts a falling vehicle's 0.2 g by more than
-- a g within milliseconds and is seen, where 2 g waited for the downhill feet (150-180 ms later on
-- ArduCopter SITL at 45 and 55 deg); at the cut, before the thrust decays, it is the 2 g rule.
-- The rise counts only RISE_AFTER_MS after the cut, the rotors' time constant: the thrust and the
-- vibration the rotors make (an imbalance, the blades' thrust ripple: both their speed squared)
-- have fallen to e^-2, 14 %, of hover. Before it, the rotors' vibration at hover is still there,
-- and a trough followed by a crest read as a rise: on a vehicle at twice ArduPilot's acceptable
-- vibration the rule fired 2-8 ms after the cut, 27 cm above the roof (issue 40;
-- tests/firmware/test_script_vibration.py). Before it, the 2 g rule (and the range) alone.
local RISE_AFTER_MS = 50
-- The roof pushes on the feet within its friction cone, and the legs carry that push to the body
-- from below: on the steepest roof the feet hold (50 deg, mu 0.8: the cone reaches 89 deg from the
-- vertical) the specific force still points up the body (FRD z < 0), as does the rotors' thrust.
-- A reading pointing down the body is no contact: a 6 g, 40 ms accelerometer spike 0.09 s into
-- the fall from the cut (soak at ea848b5, landing 143, 50 deg) fired reverse thrust 0.12 s before
-- the feet met the roof. The impact needs the body-up share of the reading above this (m/s^2).
IMPACT.UP = 0.0
-- ArduCopter reads the rangefinder at 20 Hz (ArduCopter/Copter.cpp), this script every 2-10 ms:
-- only a new sample (a new driver reading time) counts. Two distinct samples at or below the cut
-- height: one low glitch cannot cut.
local CUT_SAMPLES = 2
local MAX_JUMP_M = 0.25 -- a trusted reading differs from the last believed one by at most this
local MAX_RATE_MPS = 3.0 -- ...plus this much per second since it (a fast descent, a dropout)
-- readings that disagree with the believed one for this long are a real change of the ground
-- (a new chain); shorter, a glitch. A chain that starts at or below the cut height counts only
-- after this long too. Found by the soak: a 0.2-0.5 s low spike was followed reading by reading
-- and cut the motors 1.07 m above the roof.
local RESEED_MS = 600
-- The cut reckoned on the descent: ARMED with the last trusted reading (on the chain) within
-- WINDOW_M above the cut height and no reading agreeing with it for AFTER_MS (three 20 Hz samples:
-- a dropout, or a spike the chain sets aside as a glitch), the height is that reading less the
-- autopilot's descent (EKF down velocity) since it; at or below the cut height, CUT. Found by the
-- soak on ArduCopter (23bea36): a dropout 0.35 m over the roof, and a 0.47 s high spike through
-- the cut, each met the roof under power. A reading beyond the sensor's maximum (the beam past a
-- roof's edge) is evidence, not silence: no reckoning then. A reckoned cut is near the ground for
-- the impact rule until a trusted reading says otherwise. Only while descending at MIN_MPS or more:
-- a vehicle holding height stays off the roof, and one reading at the cut height never cuts.
-- A reading that stops following the descent is silence too: readings within STILL_M of the last
-- one that moved do not renew the reckoning (a sensor stuck 0.07 m above the cut height, after a
-- spike, kept agreeing with the chain and met the roof under power: soak at ea848b5, landing 140).
-- A true descent at MIN_MPS moves the reading 1 cm a 20 Hz sample; a stuck sensor repeats its value.
local RECKON = { AFTER_MS = 150, WINDOW_M = 0.30, MIN_MPS = 0.2, STILL_M = 0.01 }
-- the missed-impact bound: the fall from the cut height at the descent speed, plus the rotors'
-- spin-down (twice the model's 50 ms time constant) and one range sample to judge by
MS.THRUST_DECAY, MS.RANGE_PERIOD = 100, 50
-- A cut whose bound passes with the range at or below the cut height but the vehicle still
-- falling freely (the accelerometer under LEAVE.FALL_SUPPORT: nothing carries it) was made higher
-- than the range said: a low reading that lasted past RESEED_MS (something under the beam, a stuck
-- sensor). HOLD there met the roof with the motors held and no reverse thrust on the impact (a
-- false cut about 1 m up); the motors given back cannot stop a vehicle falling at 4 m/s within the
-- cut height the range reads either. So the cut stands and the impact is watched for, up to
-- MS.FALL_WAIT past the bound (a further 3 m of fall); then HOLD as before.
-- left the roof (slid off an edge, or high above it): this many distinct samples in a row, each
-- with all three of
--  * the body within LEAVE.TILT_DEG of level, and staying within it should the autopilot stop
--    its rotation at once: tilt + w^2 / (2 * LEAVE.ATT_ACCEL_DEGS2) <= LEAVE.TILT_DEG, w the body rate.
--    The beam runs along the body's down axis: tilted more, it meets a roof at a grazing angle or
--    misses it (pointing sideways or up, a tumbling or flipped vehicle reads out of range high
--    while it lies on the roof), so its range says nothing of the ground below; and the autopilot
--    could not fly such a vehicle, only spin its motors up on the roof. A vehicle sliding off a
--    roof is tilted like it: 60 deg covers the steepest roof the feet hold on (about 50 deg) with
--    10 deg for the pivot. A vehicle cartwheeling down the roof (200-360 deg/s) passes upright
--    between its bounces, airborne, its beam along the roof: its rotation keeps it out;
--  * the beam's vertical share, range * cos(tilt), farther than the cut height plus
--    LEAVE.MARGIN_M (or out of range high). The margin covers a beam tilted by the touchdown's
--    pivot on a steep roof;
--  * the vehicle falling: the accelerometer's upward specific force in the earth frame under
--    LEAVE.FALL_SUPPORT. On a roof of slope a the roof carries all of the weight but the downward part
--    of a slide's acceleration, g * sin(a) * (sin(a) - mu * cos(a)) <= g * sin(a)^2: at least
--    g / 2 up to 45 deg even on ice (0.9 g on shingles, mu_k 0.8). Off the roof nothing carries
--    it: 0 with the motors stopped, below 0 with reverse thrust pushing it down.
-- Found on a 45 deg roof: a vehicle tumbling over on the roof read out of range high (its beam
-- pointing up the roof) and had its motors released by the range rule alone.
-- ATT_ACCEL_DEGS2: the fastest the attitude controller changes a roll or pitch rate, ArduCopter's
-- default ATC_ACCEL_R_MAX / ATC_ACCEL_P_MAX (AC_AttitudeControl.h, ACCEL_RP_MAX_DEFAULT_CDSS
-- 110000 cdeg/s/s)
local LEAVE = { SAMPLES = 2, MARGIN_M = 0.30, TILT_DEG = 60, ATT_ACCEL_DEGS2 = 1100 }
LEAVE.FALL_SUPPORT = 0.5 * GRAVITY
-- still enough to disarm: body rates and the autopilot's velocity estimate both small, and held so
-- for MS ms. One sample is not enough: a sliding vehicle whose feet stick for an instant, or one at
-- the top of a bounce, reads still for a few ms. 1 s is ArduCopter's own land detector's time
-- (LAND_DETECTOR_TRIGGER_SEC, ArduCopter/land_detector.cpp), the check this disarm goes around.
local STILL = { GYRO_DEGS = 5, SPEED_MPS = 0.10, MS = 1000 }
-- the descent stopped by the script (an ARMED reflex whose companion went silent, or a fault in
-- ARMED): a GUIDED velocity target MPS up, re-sent every RESEND_MS for MS; ArduCopter then drops it
-- after GUID_TIMEOUT and holds. Not in GUIDED: the vehicle is the pilot's, nothing is sent. GUIDED
-- refusing the target: BRAKE.
-- A lapse with the trusted reading within GRACE_M of the cut height, descending: a climb from there
-- stops on the roof (ArduCopter took 0.13 m to turn a 0.5 m/s descent round; the feet met a 20 deg
-- roof at 0.23 m/s, 2026-12-07), so the reflex keeps its cut a while more, once: the descent goes
-- on to the cut, or stops (GUID_TIMEOUT ends it with the validity) near the cut height and climbs
-- from there. GRACE_M was measured at AT_MPS; a faster descent needs room as its square (a braking
-- distance), and the cut is kept for as long as braking to rest across that band takes (2 x
-- band / speed: 600 ms at 0.5 m/s, 1.2 s at 1 m/s).
local CLIMB_UP = { MPS = 0.5, MS = 2000, RESEND_MS = 100, GRACE_M = 0.15, AT_MPS = 0.5 }
local MODE = { GUIDED = 4, BRAKE = 17 }
local TILT_BOUND_MAX_DEG = 30 -- the largest take-off tilt bound a release may ask for

local IDLE, STOP, REVERSE, ARMED, CUT, RVT, HOLD, ESTOP = 0, 1, 2, 10, 11, 12, 13, 20
local CLIMB, FAULT, FAULT_HELD = 14, 30, 31

local state = IDLE
local valid_until = 0
local reverse_pct = 0
local reflex = nil -- {cut_m, impact, pct, dur_ms, ramp_ms, ramp_from, bound_ms, falling}
local setup = nil -- {ramp_ms, descent_mps}: the landing's settings, sent before ARM
local armed_cut_m = nil -- the cut height of the last accepted ARM (bounds a commanded reverse)
local entered_ms = 0
local below = 0
-- the chain of trusted readings (follow_chain): the believed reading d, when (at), since when
-- readings disagree with it, where and when the chain began, and the last reading that moved
local chain = { d = nil, at = 0, disagree = nil, seed_ms = 0, seed_d = 0, moved_d = 0, moved_at = 0 }
local last_stamp = nil -- the driver's reading time of the newest sample seen
local floor_a = nil -- the lowest filtered accel magnitude since the cut (m/s^2)
local last_d = nil -- the newest sample's distance (0: too close, huge: too far), nil before any
local far_count = 0
local silent_said = false
local said = { announce = -MS.ANNOUNCE, version = -MS.VERSION }
local rf_backend = nil
local still_since = nil -- since when the vehicle has read still (STILL), nil while it moves
local climb_until, climb_sent = nil, 0 -- the script's climb (CLIMB_UP): until when, last sent

local function now() return millis():toint() end

local function say(severity, text) gcs:send_text(severity, "SL: " .. text) end

local function announce(t)
  gcs:send_named_float("SL_STATE", state)
  said.announce = t
end

local function enter(new, t, why)
  if new ~= CLIMB then climb_until = nil end -- a climb ends with any other state
  if new ~= state then
    state = new
    entered_ms = t
    if why then say(SEV.INFO, why) end
    announce(t)
  end
end

-- the outputs last set: whether with HELD_OVERRIDE_MS (to clear when they end), and their PWM
local out = { long = false, pwm = PWM_STOP }

local function output(pwm, timeout_ms)
  timeout_ms = timeout_ms or OVERRIDE_MS
  for _, ch in ipairs(MOTORS) do
    SRV_Channels:set_output_pwm_chan_timeout(ch, pwm, timeout_ms)
  end
  out.long, out.pwm = timeout_ms > OVERRIDE_MS, pwm
end

-- a zero timeout clears the override at once (SRV_Channels::set_output_pwm_chan_timeout)
local function clear_outputs()
  for _, ch in ipairs(MOTORS) do
    SRV_Channels:set_output_pwm_chan_timeout(ch, PWM_STOP, 0)
  end
  out.long = false
end

local function reverse_pwm(pct) return math.floor(PWM_STOP - 5 * pct + 0.5) end

local function ack(chan, command, result, request, sysid, compid)
  local payload = string.pack("<HBBiBB", command, result, 0, request, sysid, compid)
  mavlink:send_chan(chan, MSG.COMMAND_ACK, payload)
end

local function bad(x, lo, hi) return x ~= x or x < lo or x > hi end

local function landing() return state == CUT or state == RVT or state == HOLD end

-- the downward rangefinder's driver, found once it exists
local function down_backend()
  if rf_backend == nil then
    for i = 0, rangefinder:num_sensors() - 1 do
      ---@type AP_RangeFinder_Backend_ud
      local backend = rangefinder:get_backend(i)
      if backend ~= nil and backend:orientation() == DOWN then
        rf_backend = backend
        break
      end
    end
  end
  return rf_backend
end

-- the driver's reading time of its newest sample (ms), or nil without a downward rangefinder
local function reading_stamp()
  local backend = down_backend()
  if backend == nil then return nil end
  ---@type RangeFinder_State_ud
  local sample = backend:get_state()
  return sample:last_reading():toint()
end

-- a downward range the cut may rely on, or nil
local function trusted_range()
  if rangefinder:status_orient(DOWN) ~= RF.GOOD then return nil end
  local d = rangefinder:distance_orient(DOWN)
  if d < rangefinder:min_distance_orient(DOWN) or d > rangefinder:max_distance_orient(DOWN) then return nil end
  if rangefinder:signal_quality_pct_orient(DOWN) == 0 then return nil end
  return d
end

-- what the range says of the ground after the cut: a distance, 0 when too close to measure,
-- math.huge when beyond the sensor, nil when it says nothing
local function ground_range()
  local status = rangefinder:status_orient(DOWN)
  if status == RF.LOW then return 0 end
  if status == RF.HIGH then return math.huge end
  return trusted_range()
end

-- moving too much to disarm: why (true when not ``describe``d), or nil when still
local function moving(describe)
  local g = ins:get_gyro(0):length()
  if g > math.rad(STILL.GYRO_DEGS) then
    return describe and string.format("turning %.0f deg/s", math.deg(g)) or true
  end
  ---@type Vector3f_ud
  local v = ahrs:get_velocity_NED()
  if v == nil then return describe and "velocity unknown" or true end
  local speed = v:length()
  if speed > STILL.SPEED_MPS then return describe and string.format("moving %.2f m/s", speed) or true end
  return nil
end

-- why the vehicle may not be disarmed now (moving, or not yet still for STILL.MS; true when not
-- ``describe``d: every update asks, without building strings), or nil. A single moving sample
-- restarts the window
local function not_still(t, describe)
  local why = moving(describe)
  if why then
    still_since = nil
    return why
  end
  still_since = still_since or t
  if t - still_since < STILL.MS then
    if not describe then return true end
    return string.format("still for %.1f s of %.1f", (t - still_since) / 1000, STILL.MS / 1000)
  end
  return nil
end

-- the climb (CLIMB_UP) while it lasts: re-sent every RESEND_MS in GUIDED; over, or the vehicle
-- no longer in GUIDED (the pilot's or the companion's mode change), it ends
local function climb_step(t)
  if climb_until == nil then return end
  if t >= climb_until or vehicle:get_mode() ~= MODE.GUIDED then
    climb_until = nil
  elseif t - climb_sent >= CLIMB_UP.RESEND_MS then
    ---@type Vector3f_ud
    local up = Vector3f()
    up:z(-CLIMB_UP.MPS) -- NED: up is negative
    climb_sent = t
    local ok, done = pcall(function() return vehicle:set_target_velocity_NED(up) end)
    if not (ok and done) then
      climb_until = nil
      vehicle:set_mode(MODE.BRAKE)
    end
  end
end

-- stop a GUIDED descent: the companion's last target runs on for GUID_TIMEOUT, the reflex that
-- protected it is gone. Starts the climb; says what was done
local function stop_descent(t)
  if vehicle:get_mode() ~= MODE.GUIDED then return "not in GUIDED, left to the pilot" end
  climb_until, climb_sent = t + CLIMB_UP.MS, t - CLIMB_UP.RESEND_MS
  climb_step(t)
  if climb_until ~= nil then return "climbing" end
  if vehicle:get_mode() == MODE.BRAKE then return "BRAKE" end
  return "descent not stopped"
end

local function tilt_deg()
  local c = math.cos(ahrs:get_roll_rad()) * math.cos(ahrs:get_pitch_rad())
  return math.deg(math.acos(math.max(-1, math.min(1, c))))
end

local function release(t, why)
  reflex = nil
  enter(IDLE, t, why)
end

-- the free fall from the cut height at the descent speed, plus spin-down and a range sample (ms)
local function missed_impact_ms(cut_m, descent_mps)
  local fall_s = (math.sqrt(descent_mps ^ 2 + 2 * GRAVITY * cut_m) - descent_mps) / GRAVITY
  return math.floor(fall_s * 1000 + MS.THRUST_DECAY + MS.RANGE_PERIOD + 0.5)
end

-- the actuator command: release, stop, reverse at N %
local function actuator(p, t)
  local action = p[1]
  if action ~= ACT.RELEASE and action ~= ACT.STOP and action ~= ACT.REVERSE then return DENIED, "unknown action" end
  if landing() then return TEMP_REJECTED, "motors held: disarm or take-off release" end
  if action == ACT.RELEASE then
    release(t, "released")
    return ACCEPTED
  end
  if bad(p[2], 0, 100) then return DENIED, "thrust percent out of 0..100" end
  if bad(p[3], 20, 5000) then return DENIED, "validity out of 20..5000 ms" end
  if not arming:is_armed() then return TEMP_REJECTED, "disarmed" end
  if state == ESTOP then return TEMP_REJECTED, "emergency stop" end
  if action == ACT.REVERSE and (armed_cut_m == nil or last_d == nil or last_d > armed_cut_m) then
    return TEMP_REJECTED, "reverse: range above the cut height"
  end
  reflex = nil
  reverse_pct = p[2]
  valid_until = t + p[3]
  enter(action == ACT.STOP and STOP or REVERSE, t)
  return ACCEPTED
end

local function arm_reflex(p, t)
  local action = p[1]
  if bad(p[2], 0.10, 2.00) then return DENIED, "cut height out of 0.10..2.00 m" end
  if bad(p[3], IMPACT.MIN, 200) then return DENIED, "impact threshold out of 19.6..200" end
  if bad(p[4], 0, 100) then return DENIED, "thrust percent out of 0..100" end
  if bad(p[5], 0, 5000) then return DENIED, "reverse duration out of 0..5000 ms" end
  if bad(p[6], 100, 10000) then return DENIED, "validity out of 100..10000 ms" end
  if not arming:is_armed() then return TEMP_REJECTED, "disarmed" end
  if state == ESTOP then return TEMP_REJECTED, "emergency stop" end
  if action == RFX.END_REVERSE then
    if not landing() then return TEMP_REJECTED, "no landing under way" end
    valid_until = t + p[6]
    if state == RVT and reflex.ramp_from == nil then reflex.dur_ms = 0 end
    return ACCEPTED
  end
  if setup == nil then return TEMP_REJECTED, "reflex not set up" end
  if down_backend() == nil then return TEMP_REJECTED, "no downward rangefinder" end
  valid_until = t + p[6]
  if state == RVT then
    -- a refresh during reverse thrust sets its duration, counted from the impact: the companion
    -- shortens it once the vehicle is still; a silent companion leaves the armed bound in force.
    -- Once the thrust has begun to ramp down, it only ends: the refresh renews the validity.
    if reflex.ramp_from == nil then reflex.dur_ms = p[5] end
    return ACCEPTED
  end
  if state == CUT or state == HOLD then return ACCEPTED end -- a refresh
  reflex = {
    cut_m = p[2], impact = p[3], pct = p[4], dur_ms = p[5], ramp_ms = setup.ramp_ms, ramp_from = nil,
    bound_ms = missed_impact_ms(p[2], setup.descent_mps),
  }
  armed_cut_m = p[2]
  -- neither an arm nor a refresh restarts the chain of readings (follow_chain): restarted by
  -- each refresh every 300 ms, a chain that had to start below the cut height (the ground came
  -- closer during a stuck reading) never lasted RESEED_MS, and the vehicle sat powered on the
  -- roof (found by the soak); restarted by the arm, an arm late in the descent found the range
  -- already at the cut height and waited RESEED_MS while the feet met the roof
  if state == ARMED then return ACCEPTED end
  below = 0
  enter(ARMED, t)
  return ACCEPTED
end

local function disarm_request(t)
  if not arming:is_armed() then return ACCEPTED end
  if state ~= HOLD and state ~= STOP then return TEMP_REJECTED, "disarm: motors not held stopped" end
  local why = not_still(t, true)
  if why then return TEMP_REJECTED, "disarm: " .. why end
  arming:disarm()
  if arming:is_armed() then return TEMP_REJECTED, "disarm: refused by the autopilot" end
  release(t, "disarmed on the companion's request")
  return ACCEPTED
end

local function takeoff_release(p, t)
  if bad(p[2], 1, TILT_BOUND_MAX_DEG) then return DENIED, "take-off tilt bound out of 1..30 deg" end
  if state == CUT or state == RVT then return TEMP_REJECTED, "take-off release: landing under way" end
  if state == HOLD or state == STOP then
    local tilt = tilt_deg()
    if tilt > p[2] then return TEMP_REJECTED, string.format("take-off release: tilted %.0f deg", tilt) end
  end
  release(t, "released for take-off")
  return ACCEPTED
end

-- the landing reflex: set up, arm (or refresh), end the reverse thrust, abort, release, disarm
local function reflex_command(p, t)
  local action = p[1]
  if action == RFX.ABORT then
    if landing() then return TEMP_REJECTED, "motors held: disarm or take-off release" end
    if state == ARMED or state == CLIMB or reflex ~= nil then release(t, "reflex aborted") end
    return ACCEPTED
  elseif action == RFX.ARM or action == RFX.END_REVERSE then
    return arm_reflex(p, t)
  elseif action == RFX.SETUP then
    if bad(p[2], 0, 3000) then return DENIED, "reverse ramp out of 0..3000 ms" end
    if bad(p[3], 0.1, 3.0) then return DENIED, "descent rate out of 0.1..3.0 m/s" end
    setup = { ramp_ms = p[2], descent_mps = p[3] }
    return ACCEPTED
  elseif action == RFX.TAKEOFF_RELEASE then
    return takeoff_release(p, t)
  elseif action == RFX.DISARM then
    return disarm_request(t)
  end
  return DENIED, "unknown reflex action"
end

-- a COMMAND_LONG for this script: its command, parameters 1..6, request number (nil: not a
-- valid one) and whether it is addressed to this vehicle; nil for any other message
local function decode(msg)
  if string.unpack("<I3", msg, 10) ~= MSG.COMMAND_LONG then return nil end
  local p1, p2, p3, p4, p5, p6, p7, command, tsys, tcomp = string.unpack("<fffffffHBB", msg, 13)
  if command ~= CMD_ACTUATOR and command ~= CMD_REFLEX then return nil end
  local request = nil
  if not bad(p7, 1, REQUEST_MAX) and p7 == math.floor(p7) then request = math.floor(p7) end
  local ours = tsys == (param:get("MAV_SYSID") or 1) and (tcomp == 0 or tcomp == 1)
  return command, { p1, p2, p3, p4, p5, p6 }, request, ours
end

-- the COMMAND_ACK to msg's sender (echoing the request number), then the reason of a refusal
local function answer(msg, chan, command, result, request, why)
  local sysid, compid = string.unpack("<BB", msg, 8)
  ack(chan, command, result, request or 0, sysid, compid)
  if why then say(SEV.WARNING, why) end
end

local function handle(msg, chan, t)
  local command, p, request, ours = decode(msg)
  if command == nil then return end
  local result, why = DENIED, nil
  if request == nil then
    why = "bad request number"
  elseif not ours then
    why = "command for another vehicle"
  else
    if command == CMD_ACTUATOR then
      result, why = actuator(p, t)
    else
      result, why = reflex_command(p, t)
    end
  end
  answer(msg, chan, command, result, request, why)
end

-- whether a sample of range g (m) says the vehicle is off the roof (see LEAVE.SAMPLES): upright
-- enough for the beam to point at the ground below, and to be flown; that ground far below; falling
local function off_roof(g, cut_m)
  local roll, pitch = ahrs:get_roll_rad(), ahrs:get_pitch_rad()
  local c = math.cos(roll) * math.cos(pitch) -- cos(tilt): the beam's vertical share
  local w = math.deg(ins:get_gyro(0):length())
  local stopped_at = math.deg(math.acos(math.max(-1, math.min(1, c)))) + w * w / (2 * LEAVE.ATT_ACCEL_DEGS2)
  if stopped_at > LEAVE.TILT_DEG or g * c <= cut_m + LEAVE.MARGIN_M then return false end
  ---@type Vector3f_ud
  local a = ins:get_accel(0)
  -- the body's specific force rotated to the earth frame's down axis (ZYX Euler angles)
  local down = -math.sin(pitch) * a:x() + math.sin(roll) * math.cos(pitch) * a:y() + c * a:z()
  return -down < LEAVE.FALL_SUPPORT
end

-- a new rangefinder sample: the newest ground evidence, and how long it has read off the roof
local function note_sample(cut_m)
  local g = ground_range()
  if g == nil then return end -- no data says nothing: the last evidence stands
  last_d = g
  if cut_m ~= nil and off_roof(g, cut_m) then far_count = far_count + 1 else far_count = 0 end
end

-- a new sample on the chain of trusted readings, followed in every state, so that an arm that
-- comes late in a descent finds the chain begun above the cut height: the reading, or nil when it
-- is untrusted or a disagreement not yet lasting RESEED_MS (a glitch)
local function follow_chain(t)
  local d = trusted_range()
  if d == nil then return nil end
  -- the allowance grows over time without readings (a dropout), not while readings keep
  -- coming and disagree: a lasting spike must not grow into agreement
  local since = (chain.disagree or t) - chain.at
  if chain.d ~= nil and math.abs(d - chain.d) > MAX_JUMP_M + MAX_RATE_MPS * since / 1000 then
    chain.disagree = chain.disagree or t
    if t - chain.disagree < RESEED_MS then return nil end
    chain.d = nil -- a lasting change: a new chain, seen since the disagreement began
  end
  if chain.d == nil then chain.seed_ms, chain.seed_d = chain.disagree or t, d end
  if chain.d == nil or math.abs(d - chain.moved_d) >= RECKON.STILL_M then chain.moved_d, chain.moved_at = d, t end
  chain.disagree = nil
  chain.d, chain.at = d, t
  return d
end

-- the height reckoned from the chain's last trusted reading that moved and the descent since
-- (RECKON), or nil when the rule does not apply: a recent moving reading, one far above the cut
-- height, a young chain begun low, a reading beyond the sensor, or no velocity estimate
function RECKON.height(t, cut_m)
  if chain.d == nil or chain.d > cut_m + RECKON.WINDOW_M or t - chain.moved_at < RECKON.AFTER_MS then return nil end
  if chain.seed_d <= cut_m and chain.at - chain.seed_ms < RESEED_MS then return nil end
  if rangefinder:status_orient(DOWN) == RF.HIGH then return nil end
  ---@type Vector3f_ud|nil
  local v = ahrs:get_velocity_NED()
  if v == nil or v:z() < RECKON.MIN_MPS then return nil end
  return chain.d - v:z() * (t - chain.moved_at) / 1000
end

-- whether the ground is within the cut height for the impact rule: the newest sample says so, or
-- the cut was reckoned and no trusted reading that moved since it says farther
function RECKON.near()
  if last_d ~= nil and last_d <= reflex.cut_m then return true end
  return reflex.reckoned == true and not (chain.moved_at > entered_ms and chain.d > reflex.cut_m)
end

-- the impact's ground evidence: near (above), or the newest sample one the chain sets aside (a
-- glitch) while the chain reads the cut height or less. A 0.49 s spike reading 1.19 m began 0.05 s
-- before the feet met a 7 deg roof and hid the impact; at the bound the spike read as a false cut
-- and the motors were given back on the roof (soak at 7425eb6, landing 64).
function RECKON.ground()
  return RECKON.near() or (chain.disagree ~= nil and chain.d ~= nil and chain.d <= reflex.cut_m)
end

-- the reflex: cut on a trusted range at or below the cut height, reverse at impact; ``d`` is
-- this update's sample on the chain (nil: none, untrusted, or a glitch)
local function run_reflex(t, fresh, d)
  if state == ARMED then
    if t >= valid_until then
      -- the companion silent: its descent target runs on for GUID_TIMEOUT, the reflex does not
      ---@type Vector3f_ud|nil
      local v = ahrs:get_velocity_NED()
      local vz = v ~= nil and v:z() or 0
      local band = CLIMB_UP.GRACE_M * math.max(1, (vz / CLIMB_UP.AT_MPS) ^ 2)
      if not reflex.graced and chain.d ~= nil and chain.d <= reflex.cut_m + band and vz >= RECKON.MIN_MPS then
        reflex.graced = true
        valid_until = t + math.floor(2000 * band / vz)
        say(SEV.WARNING, string.format("lapse at %.2f m, cut %.2f m: cut kept", chain.d, reflex.cut_m))
        return
      end
      local how = stop_descent(t)
      reflex = nil
      enter(climb_until and CLIMB or IDLE, t, "reflex validity lapsed, " .. how)
      return
    end
    local h = RECKON.height(t, reflex.cut_m)
    if h ~= nil and h <= reflex.cut_m then
      local why = string.format("range lost %d ms: reckoned cut at %.2f m", t - chain.moved_at, h)
      far_count, floor_a, reflex.reckoned = 0, nil, true
      enter(CUT, t, why)
      return
    end
    if not fresh then return end -- only a new sample says anything new
    if d == nil or (chain.seed_d <= reflex.cut_m and t - chain.seed_ms < RESEED_MS) then
      below = 0
      return
    end
    if d <= reflex.cut_m then below = below + 1 else below = 0 end
    if below >= CUT_SAMPLES then
      far_count = 0
      floor_a = nil
      enter(CUT, t)
    end
  elseif state == CUT then
    -- reverse thrust only on the ground: an impact with the range at or below the cut height
    local near = RECKON.near()
    ---@type Vector3f_ud
    local av = ins:get_accel(0)
    local a = av:length()
    if floor_a == nil or a < floor_a then floor_a = a end
    local threshold = reflex.impact
    if t - entered_ms >= RISE_AFTER_MS then
      threshold = math.min(threshold, floor_a + reflex.impact - GRAVITY)
    end
    if (near or RECKON.ground()) and a > threshold and -av:z() > IMPACT.UP then
      enter(RVT, t)
    elseif t - entered_ms > reflex.bound_ms then
      local far = not near
      -- judged once, at the bound: the range near and the vehicle still falling freely means
      -- the cut came higher than the range said; the impact is then watched for (MS.FALL_WAIT),
      -- also while the contact lifts the filtered reading through LEAVE.FALL_SUPPORT
      if reflex.falling == nil then reflex.falling = not far and a < LEAVE.FALL_SUPPORT end
      if reflex.falling then
        if t - entered_ms > reflex.bound_ms + MS.FALL_WAIT then
          enter(HOLD, t, "no impact seen, holding motors stopped")
        end
      elseif far and a < LEAVE.FALL_SUPPORT then
        -- falling freely with the ground far below: a false cut. Carried by something (a >= 0.5 g,
        -- the motors long stopped) it stands on the roof, whatever the range says: HOLD
        release(t, "false cut, motors released")
      else
        enter(HOLD, t, "no impact seen, holding motors stopped")
      end
    end
  elseif state == RVT then
    -- the duration over, the thrust falls linearly to zero over ramp_ms (the legs, bent under
    -- the thrust, spring back slowly enough for the feet to hold), then HOLD
    if reflex.ramp_from == nil and t - entered_ms >= reflex.dur_ms then reflex.ramp_from = t end
    if reflex.ramp_from ~= nil and t - reflex.ramp_from >= reflex.ramp_ms then enter(HOLD, t) end
  elseif state == HOLD then
    if t >= valid_until then
      -- a silent companion: disarm, but never a vehicle still moving (a slide, a pivot): still for
      -- STILL.MS
      local why = not_still(t, true)
      if why == nil then
        arming:disarm()
        release(t, "companion silent after landing: disarmed")
      elseif not silent_said and still_since == nil then
        silent_said = true
        say(SEV.WARNING, "companion silent, " .. why .. ": holding")
      end
    else
      silent_said = false
    end
  end
  -- off the roof (an edge, or high above it): stopped or reversed motors would drop it; the
  -- autopilot, still armed in its flying mode, can fly it
  if (state == RVT or state == HOLD) and far_count >= LEAVE.SAMPLES then
    release(t, "left the roof: motors released")
  end
end

-- one run of the script, unprotected (update() runs it under pcall): the delay to the next
local function step()
  local t = now()
  not_still(t) -- the stillness window follows every update
  if SRV_Channels:get_emergency_stop() then
    reflex = nil
    enter(ESTOP, t)
  elseif state == ESTOP then
    enter(IDLE, t)
  end
  local stamp = reading_stamp()
  local fresh = stamp ~= nil and stamp ~= last_stamp
  last_stamp = stamp
  local d = nil
  if fresh then
    note_sample(reflex and reflex.cut_m)
    d = follow_chain(t)
  end
  while true do
    local msg, chan = mavlink:receive_chan()
    if msg == nil then break end
    handle(msg, chan, t)
  end
  if state ~= IDLE and state ~= ESTOP and not arming:is_armed() then
    release(t, nil)
  end
  if (state == STOP or state == REVERSE) and t >= valid_until then
    enter(IDLE, t, "command validity lapsed")
  end
  if reflex ~= nil then run_reflex(t, fresh, d) end
  climb_step(t)
  if state == CLIMB and climb_until == nil then enter(IDLE, t, "climb over") end

  if state == HOLD or state == CUT then
    output(PWM_STOP, HELD_OVERRIDE_MS)
  elseif state == STOP then
    output(PWM_STOP)
  elseif state == REVERSE then
    output(reverse_pwm(reverse_pct))
  elseif state == RVT then
    local pct = reflex.pct
    if reflex.ramp_from ~= nil then pct = pct * (1 - (t - reflex.ramp_from) / reflex.ramp_ms) end
    output(reverse_pwm(pct), HELD_OVERRIDE_MS)
  elseif out.long then
    clear_outputs() -- released, disarmed or emergency stop: the mixer (or nothing) at once
  end

  if t - said.announce >= MS.ANNOUNCE then announce(t) end
  if t - said.version >= MS.VERSION then
    gcs:send_named_float("SL_VER", VERSION)
    said.version = t
  end
  if state == IDLE or state == ESTOP then return MS.IDLE end
  return MS.FAST
end

-- A Lua error stops an ArduPilot script (lua_scripts::run_next_script removes it), and with it
-- every override within OVERRIDE_MS or HELD_OVERRIDE_MS: the mixer spins the motors up on the
-- roof, or mid-fall after the cut, and an ARMED descent goes on with no reflex. So the update runs
-- under pcall (ArduPilot's own examples/protected_call.lua), and an error leaves a defined safe
-- state, reported as SL_STATE and STATUSTEXT:
--  * FAULT_HELD (31), from CUT, RVT or HOLD (armed, no emergency stop): the motors held stopped
--    (a reverse thrust ramped down over the SETUP's ramp), disarmed once still for STILL.MS or
--    on the companion's DISARM, released by the emergency stop or a disarm;
--  * FAULT (30), from any other state: the motors with the autopilot; from ARMED (or CLIMB) the
--    descent stopped first (stop_descent: the climb).
-- A fault is kept until the script restarts (a reboot): every command but DISARM and ABORT (which
-- ends a climb) is refused "script fault". Exceeding ArduPilot's instruction budget cannot be
-- caught (its hook raises again at every instruction) and still stops the script: the companion
-- treats a silent script as a dead one.
-- the fault's record (from, held, msg, t0, pwm, ramp_ms, said, set by fault.enter), and what
-- fault.last_resort holds: the motors stopped (bare), or nothing
local fault = {
  NAMES = {
    [IDLE] = "IDLE", [STOP] = "STOP", [REVERSE] = "REVERSE", [ARMED] = "ARMED", [CUT] = "CUT", [RVT] = "RVT",
    [HOLD] = "HOLD", [CLIMB] = "CLIMB", [ESTOP] = "ESTOP",
  },
  bare = false,
}

function fault.name(s) return fault.NAMES[s] or tostring(s) end

-- what the fault left and the error (each STATUSTEXT holds 50 characters), MAV_SEVERITY_CRITICAL
function fault.say()
  say(2, string.format("fault in %s, %s", fault.name(fault.from), fault.how))
  say(2, ("error " .. fault.msg):sub(1, 46))
end

function fault.enter(err)
  local t = now()
  local from = state
  local held = (from == CUT or from == RVT or from == HOLD) and arming:is_armed()
    and not SRV_Channels:get_emergency_stop()
  local ramp_ms = 0
  if from == RVT and setup ~= nil then ramp_ms = setup.ramp_ms end
  local msg = tostring(err):gsub("^[^:]*%.lua:", "") -- "<line>: <message>", without the file
  fault.from, fault.held, fault.msg, fault.t0, fault.pwm, fault.ramp_ms = from, held, msg, t, out.pwm, ramp_ms
  fault.said = t
  reflex = nil
  state = held and FAULT_HELD or FAULT
  entered_ms = t
  local how = "motors with the autopilot"
  if held then
    how = "motors held stopped"
  elseif from == ARMED or from == CLIMB then
    how = stop_descent(t)
  end
  fault.how = how
  fault.say()
  announce(t)
end

-- a command while in a fault: DISARM (held and still), ABORT (ends a climb); nothing else
function fault.command(command, p, t)
  if command == CMD_REFLEX and p[1] == RFX.DISARM then
    if not arming:is_armed() then return ACCEPTED end
    if not fault.held then return TEMP_REJECTED, "disarm: motors not held stopped" end
    local why = not_still(t, true)
    if why then return TEMP_REJECTED, "disarm: " .. why end
    arming:disarm()
    if arming:is_armed() then return TEMP_REJECTED, "disarm: refused by the autopilot" end
    return ACCEPTED
  end
  if command == CMD_REFLEX and p[1] == RFX.ABORT then
    climb_until = nil
    return ACCEPTED
  end
  return TEMP_REJECTED, "script fault: reboot to clear"
end

-- one run in a fault: the safe state fault.enter left, kept
function fault.step()
  local t = now()
  local why_not = not_still(t)
  while true do
    local msg, chan = mavlink:receive_chan()
    if msg == nil then break end
    local command, p, request, ours = decode(msg)
    if command ~= nil then
      local result, why = DENIED, "bad request number"
      if request ~= nil then
        if ours then
          result, why = fault.command(command, p, t)
        else
          why = "command for another vehicle"
        end
      end
      answer(msg, chan, command, result, request, why)
    end
  end
  if fault.held and arming:is_armed() and not SRV_Channels:get_emergency_stop() and why_not == nil then
    arming:disarm() -- still on the roof: the landing is over
  end
  if fault.held and (SRV_Channels:get_emergency_stop() or not arming:is_armed()) then
    fault.held = false
    state = FAULT
    say(SEV.INFO, arming:is_armed() and "fault: motors released (emergency stop)" or "fault: disarmed")
    announce(t)
  end
  climb_step(t)
  if fault.held then
    local pwm = PWM_STOP
    if fault.pwm < PWM_STOP and t - fault.t0 < fault.ramp_ms then
      pwm = math.floor(fault.pwm + (PWM_STOP - fault.pwm) * (t - fault.t0) / fault.ramp_ms + 0.5)
    end
    output(pwm, HELD_OVERRIDE_MS)
  elseif out.long then
    clear_outputs()
  end
  if t - fault.said >= MS.FAULT_SAY then
    fault.said = t
    fault.say()
  end
  if t - said.announce >= MS.ANNOUNCE then announce(t) end
  if t - said.version >= MS.VERSION then
    gcs:send_named_float("SL_VER", VERSION)
    said.version = t
  end
  if fault.held or climb_until ~= nil then return MS.FAST end
  return MS.IDLE
end

-- when the fault handling itself raised: only the outputs, and the state announced
function fault.last_resort()
  pcall(function()
    local t = now()
    if fault.bare and arming:is_armed() and not SRV_Channels:get_emergency_stop() then
      for _, ch in ipairs(MOTORS) do
        SRV_Channels:set_output_pwm_chan_timeout(ch, PWM_STOP, HELD_OVERRIDE_MS)
      end
    elseif fault.bare then
      fault.bare = false
      for _, ch in ipairs(MOTORS) do
        SRV_Channels:set_output_pwm_chan_timeout(ch, PWM_STOP, 0)
      end
    end
    if t - said.announce >= MS.ANNOUNCE then
      said.announce = t
      gcs:send_named_float("SL_STATE", fault.bare and FAULT_HELD or FAULT)
    end
  end)
  return fault.last_resort, MS.FAST
end

function fault.loop()
  local ok, delay = pcall(fault.step)
  if ok then return fault.loop, delay end
  fault.bare = fault.held == true
  return fault.last_resort, MS.FAST
end

local function update()
  local ok, delay = pcall(step)
  if ok then return update, delay end
  fault.bare = state == CUT or state == RVT or state == HOLD
  if pcall(fault.enter, delay) then return fault.loop, MS.FAST end
  return fault.last_resort, MS.FAST
end

mavlink:init(8, 1)
mavlink:register_rx_msgid(MSG.COMMAND_LONG)
mavlink:block_command(CMD_ACTUATOR)
mavlink:block_command(CMD_REFLEX)
gcs:send_text(SEV.INFO, "SL: slopelander script v" .. VERSION .. " ready")
return update, MS.IDLE
