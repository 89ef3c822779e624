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
local VERSION = 4 -- 2: a refresh during RVT sets its duration (the companion ends it on evidence)
-- 3: the reflex arm's param 7 ramps the reverse thrust down over that many ms when it ends
-- 4: param 7 of every command is a request number, echoed in COMMAND_ACK.result_param2; the ramp
--    and the descent rate move to a SETUP request (reflex action 3) sent before ARM; new reflex
--    actions END_REVERSE 2, TAKEOFF_RELEASE 4 (only level), DISARM 5 (only held and still); the
--    cut counts distinct rangefinder samples (the driver's reading time), 2 of them; reverse
--    thrust only with the range at or below the cut height; RVT and HOLD give the motors back
--    when the range says the vehicle left the roof; the missed-impact bound follows the cut height
--    and the descent rate; an abort or release during CUT/RVT/HOLD is refused; a silent
--    companion's HOLD disarms only while still; the impact threshold is at least 2 g.
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
-- On the ground (RVT, HOLD) the override outlasts a stalled scripting thread. ArduPilot counts an
-- override's timeout in main-loop ticks (SRV_Channels::set_output_pwm_chan_timeout), not in the
-- script's own runs: a scripting thread starved for more than OVERRIDE_MS hands the outputs back
-- to the mixer, and an armed mixer on a steep roof fights the tilt at full forward thrust (seen on
-- ArduCopter SITL at 55 deg: 40 ms at 1600-1976 us, twice in 25 s). Stopped or reversed motors on
-- the ground are the safe side of a stall, so they hold this long; leaving RVT/HOLD clears them.
local GROUND_OVERRIDE_MS = 250
local FAST_MS = 2 -- update period while anything is active
local IDLE_MS = 10 -- update period otherwise (command latency)
local ANNOUNCE_MS = 200 -- SL_STATE at 5 Hz
local VERSION_MS = 1000
local GRAVITY = 9.80665
-- The filtered accelerometer reads the thrust over the mass, ~1 g, in the steady descent at the
-- cut, and falls toward 0 g as the thrust decays: an impact threshold must lie well above 1 g.
-- 2 g leaves a full g for the controller's corrections and the vibration left after the filter.
local IMPACT_MIN = 2 * GRAVITY
-- After the cut the specific force only falls (the thrust decays, the vehicle falls freely) until
-- something pushes on the vehicle: the threshold counts from the lowest reading since the cut,
-- threshold - 1 g above it, never more than the threshold itself. A soft first contact (an uphill
-- leg near the horizontal slips at a small foot force) lifts a falling vehicle's 0.2 g by more than
-- a g within milliseconds and is seen, where 2 g waited for the downhill feet (150-180 ms later on
-- ArduCopter SITL at 45 and 55 deg); at the cut, before the thrust decays, it is the 2 g rule.
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
-- the missed-impact bound: the fall from the cut height at the descent speed, plus the rotors'
-- spin-down (twice the model's 50 ms time constant) and one range sample to judge by
local THRUST_DECAY_MS = 100
local RANGE_PERIOD_MS = 50
-- left the roof (slid off an edge, or high above it): this many distinct samples in a row, each
-- with all three of
--  * the body within LEAVE_TILT_DEG of level, and staying within it should the autopilot stop
--    its rotation at once: tilt + w^2 / (2 * ATT_ACCEL_DEGS2) <= LEAVE_TILT_DEG, w the body rate.
--    The beam runs along the body's down axis: tilted more, it meets a roof at a grazing angle or
--    misses it (pointing sideways or up, a tumbling or flipped vehicle reads out of range high
--    while it lies on the roof), so its range says nothing of the ground below; and the autopilot
--    could not fly such a vehicle, only spin its motors up on the roof. A vehicle sliding off a
--    roof is tilted like it: 60 deg covers the steepest roof the feet hold on (about 50 deg) with
--    10 deg for the pivot. A vehicle cartwheeling down the roof (200-360 deg/s) passes upright
--    between its bounces, airborne, its beam along the roof: its rotation keeps it out;
--  * the beam's vertical share, range * cos(tilt), farther than the cut height plus
--    LEAVE_MARGIN_M (or out of range high). The margin covers a beam tilted by the touchdown's
--    pivot on a steep roof;
--  * the vehicle falling: the accelerometer's upward specific force in the earth frame under
--    FALL_SUPPORT. On a roof of slope a the roof carries all of the weight but the downward part
--    of a slide's acceleration, g * sin(a) * (sin(a) - mu * cos(a)) <= g * sin(a)^2: at least
--    g / 2 up to 45 deg even on ice (0.9 g on shingles, mu_k 0.8). Off the roof nothing carries
--    it: 0 with the motors stopped, below 0 with reverse thrust pushing it down.
-- Found on a 45 deg roof: a vehicle tumbling over on the roof read out of range high (its beam
-- pointing up the roof) and had its motors released by the range rule alone.
local LEAVE_SAMPLES = 2
local LEAVE_MARGIN_M = 0.30
local LEAVE_TILT_DEG = 60
-- the fastest the attitude controller changes a roll or pitch rate: ArduCopter's default
-- ATC_ACCEL_R_MAX / ATC_ACCEL_P_MAX (AC_AttitudeControl.h, ACCEL_RP_MAX_DEFAULT_CDSS 110000 cdeg/s/s)
local ATT_ACCEL_DEGS2 = 1100
local FALL_SUPPORT = 0.5 * GRAVITY
-- still enough to disarm: body rates and the autopilot's velocity estimate both small
local STILL_GYRO_RADS = math.rad(5)
local STILL_SPEED_MPS = 0.10
local TILT_BOUND_MAX_DEG = 30 -- the largest take-off tilt bound a release may ask for

local IDLE, STOP, REVERSE, ARMED, CUT, RVT, HOLD, ESTOP = 0, 1, 2, 10, 11, 12, 13, 20

local state = IDLE
local valid_until = 0
local reverse_pct = 0
local reflex = nil -- {cut_m, impact, pct, dur_ms, ramp_ms, ramp_from, bound_ms}
local setup = nil -- {ramp_ms, descent_mps}: the landing's settings, sent before ARM
local armed_cut_m = nil -- the cut height of the last accepted ARM (bounds a commanded reverse)
local entered_ms = 0
local below = 0
local believed, believed_ms, disagree_ms, seed_ms, seed_d = nil, 0, nil, 0, 0
local last_stamp = nil -- the driver's reading time of the newest sample seen
local floor_a = nil -- the lowest filtered accel magnitude since the cut (m/s^2)
local last_d = nil -- the newest sample's distance (0: too close, huge: too far), nil before any
local far_count = 0
local silent_said = false
local last_announce, last_version = -ANNOUNCE_MS, -VERSION_MS
local rf_backend = nil

local function now() return millis():toint() end

local function say(severity, text) gcs:send_text(severity, "SL: " .. text) end

local function announce(t)
  gcs:send_named_float("SL_STATE", state)
  last_announce = t
end

local function enter(new, t, why)
  if new ~= state then
    state = new
    entered_ms = t
    if why then say(SEV.INFO, why) end
    announce(t)
  end
end

local long_override = false -- outputs set with GROUND_OVERRIDE_MS, to clear when they end

local function output(pwm, timeout_ms)
  timeout_ms = timeout_ms or OVERRIDE_MS
  for _, ch in ipairs(MOTORS) do
    SRV_Channels:set_output_pwm_chan_timeout(ch, pwm, timeout_ms)
  end
  long_override = timeout_ms > OVERRIDE_MS
end

-- a zero timeout clears the override at once (SRV_Channels::set_output_pwm_chan_timeout)
local function clear_outputs()
  for _, ch in ipairs(MOTORS) do
    SRV_Channels:set_output_pwm_chan_timeout(ch, PWM_STOP, 0)
  end
  long_override = false
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

-- moving too much to disarm: why, or nil when still
local function moving()
  local g = ins:get_gyro(0):length()
  if g > STILL_GYRO_RADS then return string.format("turning %.0f deg/s", math.deg(g)) end
  ---@type Vector3f_ud
  local v = ahrs:get_velocity_NED()
  if v == nil then return "velocity unknown" end
  local speed = v:length()
  if speed > STILL_SPEED_MPS then return string.format("moving %.2f m/s", speed) end
  return nil
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
  return math.floor(fall_s * 1000 + THRUST_DECAY_MS + RANGE_PERIOD_MS + 0.5)
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
  if bad(p[3], IMPACT_MIN, 200) then return DENIED, "impact threshold out of 19.6..200" end
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
  local why = moving()
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
    if state == ARMED or reflex ~= nil then release(t, "reflex aborted") end
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

local function handle(msg, chan, t)
  local msgid = string.unpack("<I3", msg, 10)
  if msgid ~= MSG.COMMAND_LONG then return end
  local sysid, compid = string.unpack("<BB", msg, 8)
  local p1, p2, p3, p4, p5, p6, p7, command, tsys, tcomp = string.unpack("<fffffffHBB", msg, 13)
  if command ~= CMD_ACTUATOR and command ~= CMD_REFLEX then return end
  local request = 0
  local result, why
  local mysys = param:get("MAV_SYSID") or 1
  if bad(p7, 1, REQUEST_MAX) or p7 ~= math.floor(p7) then
    result, why = DENIED, "bad request number"
  else
    request = math.floor(p7)
    if tsys ~= mysys or (tcomp ~= 0 and tcomp ~= 1) then
      result, why = DENIED, "command for another vehicle"
    elseif command == CMD_ACTUATOR then
      result, why = actuator({ p1, p2, p3 }, t)
    else
      result, why = reflex_command({ p1, p2, p3, p4, p5, p6 }, t)
    end
  end
  ack(chan, command, result, request, sysid, compid)
  if why then say(SEV.WARNING, why) end
end

-- whether a sample of range g (m) says the vehicle is off the roof (see LEAVE_SAMPLES): upright
-- enough for the beam to point at the ground below, and to be flown; that ground far below; falling
local function off_roof(g, cut_m)
  local roll, pitch = ahrs:get_roll_rad(), ahrs:get_pitch_rad()
  local c = math.cos(roll) * math.cos(pitch) -- cos(tilt): the beam's vertical share
  local w = math.deg(ins:get_gyro(0):length())
  local stopped_at = math.deg(math.acos(math.max(-1, math.min(1, c)))) + w * w / (2 * ATT_ACCEL_DEGS2)
  if stopped_at > LEAVE_TILT_DEG or g * c <= cut_m + LEAVE_MARGIN_M then return false end
  ---@type Vector3f_ud
  local a = ins:get_accel(0)
  -- the body's specific force rotated to the earth frame's down axis (ZYX Euler angles)
  local down = -math.sin(pitch) * a:x() + math.sin(roll) * math.cos(pitch) * a:y() + c * a:z()
  return -down < FALL_SUPPORT
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
  local since = (disagree_ms or t) - believed_ms
  if believed ~= nil and math.abs(d - believed) > MAX_JUMP_M + MAX_RATE_MPS * since / 1000 then
    disagree_ms = disagree_ms or t
    if t - disagree_ms < RESEED_MS then return nil end
    believed = nil -- a lasting change: a new chain, seen since the disagreement began
  end
  if believed == nil then seed_ms, seed_d = disagree_ms or t, d end
  disagree_ms = nil
  believed, believed_ms = d, t
  return d
end

-- the reflex: cut on a trusted range at or below the cut height, reverse at impact; ``d`` is
-- this update's sample on the chain (nil: none, untrusted, or a glitch)
local function run_reflex(t, fresh, d)
  if state == ARMED then
    if t >= valid_until then
      release(t, "reflex validity lapsed")
      return
    end
    if not fresh then return end -- only a new sample says anything new
    if d == nil or (seed_d <= reflex.cut_m and t - seed_ms < RESEED_MS) then
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
    local near = last_d ~= nil and last_d <= reflex.cut_m
    local a = ins:get_accel(0):length()
    if floor_a == nil or a < floor_a then floor_a = a end
    if near and a > math.min(reflex.impact, floor_a + reflex.impact - GRAVITY) then
      enter(RVT, t)
    elseif t - entered_ms > reflex.bound_ms then
      if last_d ~= nil and last_d > reflex.cut_m then
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
      -- a silent companion: disarm, but never a vehicle still moving (a slide, a pivot)
      local why = moving()
      if why == nil then
        arming:disarm()
        release(t, "companion silent after landing: disarmed")
      elseif not silent_said then
        silent_said = true
        say(SEV.WARNING, "companion silent, " .. why .. ": holding")
      end
    else
      silent_said = false
    end
  end
  -- off the roof (an edge, or high above it): stopped or reversed motors would drop it; the
  -- autopilot, still armed in its flying mode, can fly it
  if (state == RVT or state == HOLD) and far_count >= LEAVE_SAMPLES then
    release(t, "left the roof: motors released")
  end
end

local function update()
  local t = now()
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

  if state == HOLD then
    output(PWM_STOP, GROUND_OVERRIDE_MS)
  elseif state == STOP or state == CUT then
    output(PWM_STOP)
  elseif state == REVERSE then
    output(reverse_pwm(reverse_pct))
  elseif state == RVT then
    local pct = reflex.pct
    if reflex.ramp_from ~= nil then pct = pct * (1 - (t - reflex.ramp_from) / reflex.ramp_ms) end
    output(reverse_pwm(pct), GROUND_OVERRIDE_MS)
  elseif long_override then
    clear_outputs() -- released, disarmed or emergency stop: the mixer (or nothing) at once
  end

  if t - last_announce >= ANNOUNCE_MS then announce(t) end
  if t - last_version >= VERSION_MS then
    gcs:send_named_float("SL_VER", VERSION)
    last_version = t
  end
  if state == IDLE or state == ESTOP then return update, IDLE_MS end
  return update, FAST_MS
end

mavlink:init(8, 1)
mavlink:register_rx_msgid(MSG.COMMAND_LONG)
mavlink:block_command(CMD_ACTUATOR)
mavlink:block_command(CMD_REFLEX)
gcs:send_text(SEV.INFO, "SL: slopelander script v" .. VERSION .. " ready")
return update, IDLE_MS
