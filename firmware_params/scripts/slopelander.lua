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
-- The companion decides; this script only does what cannot wait for a MAVLink round trip.
-- Contract (commands, states, validity rules): docs/onboard-script.md in slopelander.

local VERSION = 3 -- 2: a refresh during RVT sets its duration (the companion ends it on evidence)
-- 3: the reflex arm's param 7 ramps the reverse thrust down over that many ms when it ends
local CMD_ACTUATOR = 31010 -- MAV_CMD_USER_1
local CMD_REFLEX = 31011 -- MAV_CMD_USER_2
local MSG_COMMAND_LONG = 76
local MSG_COMMAND_ACK = 77
local ACCEPTED, TEMP_REJECTED, DENIED = 0, 1, 2
local SEV_WARNING, SEV_INFO = 4, 6
local DOWN = 25 -- rangefinder orientation: pitch 270, facing down
local RF_GOOD = 4
local MOTORS = { 0, 1, 2, 3 } -- SERVO1..4, 0-based channel index
local PWM_STOP = 1500
local OVERRIDE_MS = 30 -- each override lapses this soon unless refreshed
local FAST_MS = 2 -- update period while anything is active
local IDLE_MS = 10 -- update period otherwise (command latency)
local ANNOUNCE_MS = 200 -- SL_STATE at 5 Hz
local VERSION_MS = 1000
local CUT_READINGS = 3 -- consecutive trusted readings at or below the cut height
local READING_MS = 10 -- readings counted at most this often
local MAX_JUMP_M = 0.25 -- a trusted reading differs from the last believed one by at most this
local MAX_RATE_MPS = 3.0 -- ...plus this much per second since it (a fast descent, a dropout)
-- readings that disagree with the believed one for this long are a real change of the ground
-- (a new chain); shorter, a glitch. A chain that starts at or below the cut height counts only
-- after this long too. Found by the soak: a 0.2-0.5 s low spike was followed reading by reading
-- and cut the motors 1.07 m above the roof.
local RESEED_MS = 600
local MISSED_IMPACT_MS = 1000

local IDLE, STOP, REVERSE, ARMED, CUT, RVT, HOLD, ESTOP = 0, 1, 2, 10, 11, 12, 13, 20

local state = IDLE
local valid_until = 0
local reverse_pct = 0
local reflex = nil -- {cut_m, impact, pct, dur_ms, ramp_ms, ramp_from}
local entered_ms = 0
local below, last_count_ms = 0, 0
local believed, believed_ms, disagree_ms, seed_ms, seed_d = nil, 0, nil, 0, 0
local last_announce, last_version = -ANNOUNCE_MS, -VERSION_MS

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
    if why then say(SEV_INFO, why) end
    announce(t)
  end
end

local function output(pwm)
  for _, ch in ipairs(MOTORS) do
    SRV_Channels:set_output_pwm_chan_timeout(ch, pwm, OVERRIDE_MS)
  end
end

local function reverse_pwm(pct) return math.floor(PWM_STOP - 5 * pct + 0.5) end

local function ack(chan, command, result, sysid, compid)
  mavlink:send_chan(chan, MSG_COMMAND_ACK, string.pack("<HBBiBB", command, result, 0, 0, sysid, compid))
end

local function bad(x, lo, hi) return x ~= x or x < lo or x > hi end

-- a downward range the cut may rely on, or nil
local function trusted_range()
  if rangefinder:status_orient(DOWN) ~= RF_GOOD then return nil end
  local d = rangefinder:distance_orient(DOWN)
  if d < rangefinder:min_distance_orient(DOWN) or d > rangefinder:max_distance_orient(DOWN) then return nil end
  if rangefinder:signal_quality_pct_orient(DOWN) == 0 then return nil end
  return d
end

-- the actuator command: release, stop, reverse at N %
local function actuator(p1, p2, p3, t)
  if p1 ~= 0 and p1 ~= 1 and p1 ~= 2 then return DENIED, "unknown action" end
  if p1 == 0 then
    reflex = nil
    enter(IDLE, t, "released")
    return ACCEPTED
  end
  if bad(p2, 0, 100) then return DENIED, "thrust percent out of 0..100" end
  if bad(p3, 20, 5000) then return DENIED, "validity out of 20..5000 ms" end
  if not arming:is_armed() then return TEMP_REJECTED, "disarmed" end
  if state == ESTOP then return TEMP_REJECTED, "emergency stop" end
  reflex = nil
  reverse_pct = p2
  valid_until = t + p3
  enter(p1 == 1 and STOP or REVERSE, t)
  return ACCEPTED
end

-- the landing reflex: arm (or refresh) with its settings, or abort
local function arm_reflex(p, t)
  if p[1] == 0 then
    if reflex ~= nil or state == ARMED or state == CUT or state == RVT or state == HOLD then
      reflex = nil
      enter(IDLE, t, "reflex aborted")
    end
    return ACCEPTED
  end
  if p[1] ~= 1 then return DENIED, "unknown reflex action" end
  if bad(p[2], 0.10, 2.00) then return DENIED, "cut height out of 0.10..2.00 m" end
  if bad(p[3], 5, 200) then return DENIED, "impact threshold out of 5..200" end
  if bad(p[4], 0, 100) then return DENIED, "thrust percent out of 0..100" end
  if bad(p[5], 0, 5000) then return DENIED, "reverse duration out of 0..5000 ms" end
  if bad(p[6], 100, 10000) then return DENIED, "validity out of 100..10000 ms" end
  if bad(p[7], 0, 3000) then return DENIED, "reverse ramp out of 0..3000 ms" end
  if not arming:is_armed() then return TEMP_REJECTED, "disarmed" end
  if state == ESTOP then return TEMP_REJECTED, "emergency stop" end
  valid_until = t + p[6]
  if state == RVT then
    -- a refresh during reverse thrust sets its duration, counted from the impact: the companion
    -- shortens it once the vehicle is still; a silent companion leaves the armed bound in force.
    -- Once the thrust has begun to ramp down, it only ends: the refresh renews the validity.
    if reflex.ramp_from == nil then
      reflex.dur_ms = p[5]
      reflex.ramp_ms = p[7]
    end
    return ACCEPTED
  end
  if state == CUT or state == HOLD then return ACCEPTED end -- a refresh
  reflex = { cut_m = p[2], impact = p[3], pct = p[4], dur_ms = p[5], ramp_ms = p[7], ramp_from = nil }
  -- a refresh while armed keeps the chain of readings: restarting it every 300 ms, a chain that
  -- had to start below the cut height (the ground came closer during a stuck reading) never
  -- lasted RESEED_MS, and the vehicle sat powered on the roof (found by the soak)
  if state == ARMED then return ACCEPTED end
  below, believed, disagree_ms = 0, nil, nil
  enter(ARMED, t)
  return ACCEPTED
end

local function handle(msg, chan, t)
  local msgid = string.unpack("<I3", msg, 10)
  if msgid ~= MSG_COMMAND_LONG then return end
  local sysid, compid = string.unpack("<BB", msg, 8)
  local p1, p2, p3, p4, p5, p6, p7, command, tsys, tcomp = string.unpack("<fffffffHBB", msg, 13)
  if command ~= CMD_ACTUATOR and command ~= CMD_REFLEX then return end
  local result, why
  local mysys = param:get("MAV_SYSID") or 1
  if tsys ~= mysys or (tcomp ~= 0 and tcomp ~= 1) then
    result, why = DENIED, "command for another vehicle"
  elseif command == CMD_ACTUATOR then
    result, why = actuator(p1, p2, p3, t)
  else
    result, why = arm_reflex({ p1, p2, p3, p4, p5, p6, p7 }, t)
  end
  ack(chan, command, result, sysid, compid)
  if why then say(SEV_WARNING, why) end
end

-- the reflex: cut on a trusted range at or below the cut height, reverse at impact
local function run_reflex(t)
  if state == ARMED then
    if t >= valid_until then
      reflex = nil
      enter(IDLE, t, "reflex validity lapsed")
      return
    end
    local d = trusted_range()
    if d == nil then
      below = 0
      return
    end
    -- the allowance grows over time without readings (a dropout), not while readings keep
    -- coming and disagree: a lasting spike must not grow into agreement
    local since = (disagree_ms or t) - believed_ms
    if believed ~= nil and math.abs(d - believed) > MAX_JUMP_M + MAX_RATE_MPS * since / 1000 then
      disagree_ms = disagree_ms or t
      if t - disagree_ms < RESEED_MS then
        below = 0
        return
      end
      believed = nil -- a lasting change: a new chain, seen since the disagreement began
    end
    if believed == nil then seed_ms, seed_d = disagree_ms or t, d end
    disagree_ms = nil
    believed, believed_ms = d, t
    if seed_d <= reflex.cut_m and t - seed_ms < RESEED_MS then
      below = 0
      return
    end
    if t - last_count_ms >= READING_MS then
      last_count_ms = t
      if d <= reflex.cut_m then below = below + 1 else below = 0 end
    end
    if below >= CUT_READINGS then enter(CUT, t) end
  elseif state == CUT then
    if ins:get_accel(0):length() > reflex.impact then
      enter(RVT, t)
    elseif t - entered_ms > MISSED_IMPACT_MS then
      local d = trusted_range()
      if d ~= nil and d <= reflex.cut_m then
        enter(HOLD, t, "no impact seen, holding motors stopped")
      else
        reflex = nil
        enter(IDLE, t, "false cut, motors released")
      end
    end
  elseif state == RVT then
    -- the duration over, the thrust falls linearly to zero over ramp_ms (the legs, bent under
    -- the thrust, spring back slowly enough for the feet to hold), then HOLD
    if reflex.ramp_from == nil and t - entered_ms >= reflex.dur_ms then reflex.ramp_from = t end
    if reflex.ramp_from ~= nil and t - reflex.ramp_from >= reflex.ramp_ms then enter(HOLD, t) end
  elseif state == HOLD then
    if t >= valid_until then
      arming:disarm()
      reflex = nil
      enter(IDLE, t, "companion silent after landing: disarmed")
    end
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
  while true do
    local msg, chan = mavlink:receive_chan()
    if msg == nil then break end
    handle(msg, chan, t)
  end
  if state ~= IDLE and state ~= ESTOP and not arming:is_armed() then
    reflex = nil
    enter(IDLE, t)
  end
  if (state == STOP or state == REVERSE) and t >= valid_until then
    enter(IDLE, t, "command validity lapsed")
  end
  if reflex ~= nil then run_reflex(t) end

  if state == STOP or state == CUT or state == HOLD then
    output(PWM_STOP)
  elseif state == REVERSE then
    output(reverse_pwm(reverse_pct))
  elseif state == RVT then
    local pct = reflex.pct
    if reflex.ramp_from ~= nil then pct = pct * (1 - (t - reflex.ramp_from) / reflex.ramp_ms) end
    output(reverse_pwm(pct))
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
mavlink:register_rx_msgid(MSG_COMMAND_LONG)
mavlink:block_command(CMD_ACTUATOR)
mavlink:block_command(CMD_REFLEX)
gcs:send_text(SEV_INFO, "SL: slopelander script v" .. VERSION .. " ready")
return update, IDLE_MS
