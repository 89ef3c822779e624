"""The on-board Lua script run as ArduPilot runs it: real Lua 5.3 (lupa), stand-in bindings.

Only the bindings the slopelander script needs are provided, each with ArduPilot's calling
convention (``obj:method(...)``) and semantics: the script's callbacks are scheduled by the delay
they return, a Lua error stops the script and is reported as ``Lua: ...`` STATUSTEXT, an output
override from ``SRV_Channels:set_output_pwm_chan_timeout`` wins over the mixer until its timeout,
MAVLink messages reach the script in ArduPilot's ``mavlink_message_t`` byte layout. The Lua
side cannot reach Python: no ``python`` global, no eval, every attribute access refused.
"""

from __future__ import annotations

import re
import struct
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from lupa import lua53

from slopelander_sitl.vehicle.lua_limits import ardupilot_load_error

MAVLINK_MSG_T_PAYLOAD = 255  # payload bytes the script sees, zero-filled as in mavlink_message_t
INSTRUCTION_LIMIT = 100_000  # Lua VM instructions per callback before the script is stopped
MEMORY_LIMIT = 1 << 20  # bytes of Lua heap (the prelude included) before the script is stopped
LUA_ERROR_SEVERITY = 2  # MAV_SEVERITY_CRITICAL
DOWN = 25  # the one rangefinder's orientation (RNGFND1_ORIENT 25: facing down)


@dataclass(frozen=True)
class RangeReading:
    """One rangefinder's state as ArduPilot's RangeFinder library reports it."""

    distance_m: float
    status: int  # 0 NotConnected, 1 NoData, 2 OutOfRangeLow, 3 OutOfRangeHigh, 4 Good
    signal_quality_pct: int  # -1 unknown, 0 worst .. 100 best
    min_m: float
    max_m: float
    #: the driver's time of this reading (ms), ``RangeFinder_State.last_reading_ms``: a new value
    #: is a new sample (ArduCopter reads its rangefinder at 20 Hz, ``ArduCopter/Copter.cpp``)
    last_reading_ms: int = 0


class VehicleIO(Protocol):
    """What the on-board script can see and do; the simulated vehicle implements it."""

    def time_ms(self) -> int: ...
    def time_us(self) -> int: ...
    def is_armed(self) -> bool: ...
    def arm(self) -> bool: ...
    def disarm(self) -> bool: ...
    def mode(self) -> int: ...
    def set_mode(self, mode: int) -> bool: ...
    def set_target_velocity_ned(self, north: float, east: float, down: float) -> bool: ...
    def emergency_stop(self) -> bool: ...
    def accel(self) -> tuple[float, float, float]: ...
    def gyro(self) -> tuple[float, float, float]: ...
    def attitude(self) -> tuple[float, float, float]: ...
    def velocity_ned(self) -> tuple[float, float, float] | None: ...
    def rangefinder(self, orientation: int) -> RangeReading | None: ...
    def rc_pwm(self, chan: int) -> int | None: ...
    def param(self, name: str) -> float | None: ...
    def set_param(self, name: str, value: float) -> bool: ...
    def send_text(self, severity: int, text: str) -> None: ...
    def send_named_float(self, name: str, value: float) -> None: ...
    def send_mavlink(self, chan: int, msgid: int, payload: bytes) -> bool: ...
    def mixer_pwm(self, chan0: int) -> int: ...


class ScriptError(RuntimeError):
    """The script file cannot be read or does not load."""


# The binding tables, in Lua, calling the Python functions handed in as ``P``. Userdata that
# ArduPilot returns (uint32_t, Vector3f) are small Lua tables with the same methods.
_PRELUDE = r"""
local P, instruction_limit = ...
local U32 = {}
U32.__index = U32
local function u32(v) return setmetatable({v = math.floor(v) % 4294967296}, U32) end
function U32:toint() return self.v end
function U32:tofloat() return self.v + 0.0 end
local function num(a) if type(a) == "table" then return a.v end return a end
U32.__add = function(a, b) return u32(num(a) + num(b)) end
U32.__sub = function(a, b) return u32(num(a) - num(b)) end
U32.__lt = function(a, b) return num(a) < num(b) end
U32.__le = function(a, b) return num(a) <= num(b) end
U32.__eq = function(a, b) return num(a) == num(b) end
U32.__tostring = function(a) return tostring(a.v) end
function uint32_t(v) return u32(num(v or 0)) end
function millis() return u32(P.millis()) end
function micros() return u32(P.micros()) end

local Vector3f_ud = {}
Vector3f_ud.__index = Vector3f_ud
function Vector3f() return setmetatable({_x = 0.0, _y = 0.0, _z = 0.0}, Vector3f_ud) end
local function v3(x, y, z) return setmetatable({_x = x, _y = y, _z = z}, Vector3f_ud) end
function Vector3f_ud:x(v) if v ~= nil then self._x = v end return self._x end
function Vector3f_ud:y(v) if v ~= nil then self._y = v end return self._y end
function Vector3f_ud:z(v) if v ~= nil then self._z = v end return self._z end
function Vector3f_ud:length() return math.sqrt(self._x ^ 2 + self._y ^ 2 + self._z ^ 2) end

gcs = {}
function gcs:send_text(severity, text) P.send_text(severity, tostring(text)) end
function gcs:send_named_float(name, value) P.send_named_float(tostring(name), value) end

mavlink = {}
function mavlink:init(queue_length, num_rx_msgid) return P.mav_init(queue_length, num_rx_msgid) end
function mavlink:register_rx_msgid(msgid) return P.mav_register(msgid) end
function mavlink:block_command(command) return P.mav_block(command) end
function mavlink:receive_chan() return P.mav_receive() end
function mavlink:send_chan(chan, msgid, message) return P.mav_send(chan, msgid, message) end

SRV_Channels = {}
function SRV_Channels:set_output_pwm_chan_timeout(chan, pwm, timeout_ms)
  P.set_override(chan, pwm, timeout_ms)
end
function SRV_Channels:get_output_pwm_chan(chan) return P.get_output(chan) end
function SRV_Channels:get_emergency_stop() return P.estop() end

ins = {}
function ins:get_accel(instance) local x, y, z = P.accel(instance or 0); return v3(x, y, z) end
function ins:get_gyro(instance) local x, y, z = P.gyro(instance or 0); return v3(x, y, z) end

rangefinder = {}
function rangefinder:has_orientation(o) return P.rf(o, "has") end
function rangefinder:has_data_orient(o) return P.rf(o, "data") end
function rangefinder:status_orient(o) return P.rf(o, "status") end
function rangefinder:distance_orient(o) return P.rf(o, "distance") end
function rangefinder:min_distance_orient(o) return P.rf(o, "min") end
function rangefinder:max_distance_orient(o) return P.rf(o, "max") end
function rangefinder:signal_quality_pct_orient(o) return P.rf(o, "quality") end
-- one sensor, instance 0 (RNGFND1); its driver and the state it fills, as ArduPilot's
-- AP_RangeFinder_Backend and RangeFinder::RangeFinder_State (a copy, read when asked)
local AP_RangeFinder_Backend_ud = {}
AP_RangeFinder_Backend_ud.__index = AP_RangeFinder_Backend_ud
local RangeFinder_State_ud = {}
RangeFinder_State_ud.__index = RangeFinder_State_ud
local backend0 = setmetatable({}, AP_RangeFinder_Backend_ud)
function rangefinder:num_sensors() return P.rf_count() end
function rangefinder:get_backend(instance)
  if instance == 0 and P.rf_count() > 0 then return backend0 end
  return nil
end
function AP_RangeFinder_Backend_ud:orientation() return P.rf_orient() end
function AP_RangeFinder_Backend_ud:status() return P.rf(P.rf_orient(), "status") end
function AP_RangeFinder_Backend_ud:distance() return P.rf(P.rf_orient(), "distance") end
function AP_RangeFinder_Backend_ud:signal_quality() return P.rf(P.rf_orient(), "quality") end
function AP_RangeFinder_Backend_ud:get_state()
  local o = P.rf_orient()
  return setmetatable({
    _t = u32(P.rf(o, "stamp")), _status = P.rf(o, "status"), _d = P.rf(o, "distance"),
    _q = P.rf(o, "quality"),
  }, RangeFinder_State_ud)
end
function RangeFinder_State_ud:last_reading() return self._t end
function RangeFinder_State_ud:status() return self._status end
function RangeFinder_State_ud:distance() return self._d end
function RangeFinder_State_ud:signal_quality() return self._q end

ahrs = {}
-- ArduPilot 4.7 names these get_roll_rad/get_pitch_rad; the old names still answer, with a
-- "Use get_roll_rad" warning (seen on ArduCopter SITL V4.7.0-dev)
function ahrs:get_roll_rad() local r, p, y = P.attitude(); return r end
function ahrs:get_pitch_rad() local r, p, y = P.attitude(); return p end
function ahrs:get_roll() local r, p, y = P.attitude(); return r end
function ahrs:get_pitch() local r, p, y = P.attitude(); return p end
function ahrs:get_yaw() local r, p, y = P.attitude(); return y end
function ahrs:get_velocity_NED()
  local n, e, d = P.velocity()
  if n == nil then return nil end
  return v3(n, e, d)
end

arming = {}
function arming:is_armed() return P.is_armed() end
function arming:arm() return P.arm() end
function arming:disarm() return P.disarm() end

vehicle = {}
function vehicle:get_mode() return P.get_mode() end
function vehicle:set_mode(mode) return P.set_mode(mode) end
function vehicle:set_target_velocity_NED(vel) return P.set_velocity(vel:x(), vel:y(), vel:z()) end

rc = {}
function rc:get_pwm(chan) return P.rc_pwm(chan) end

param = {}
function param:get(name) return P.param_get(tostring(name)) end
function param:set(name, value) return P.param_set(tostring(name), value) end

-- runs one callback under an instruction budget, as ArduPilot's SCR_VM_I_COUNT. Over it, the hook
-- raises again at every instruction (lua_scripts::hook re-arms itself with a count of 1): a pcall
-- in the script cannot catch its way past the budget, the script is stopped
local sethook, pack, unpack, pcall, error = debug.sethook, table.pack, table.unpack, pcall, error
local over_budget
over_budget = function()
  sethook(over_budget, "", 1)
  error("exceeded time allocation", 0)
end
return function(fn)
  sethook(over_budget, "", instruction_limit)
  local r = pack(pcall(fn))
  sethook()
  if not r[1] then error(r[2], 0) end
  return unpack(r, 2, r.n)
end
"""

_BINDING_CALL = re.compile(r"\b([A-Za-z_][A-Za-z0-9_]*)\s*([:.])\s*([A-Za-z_][A-Za-z0-9_]*)\s*\(")
_LUA_LIBRARIES = {"string", "math", "table", "utf8", "coroutine", "os", "io", "debug"}


def binding_calls(source: str) -> set[str]:
    """Every call on an ArduPilot binding object in a Lua source, as ``object:method`` or
    ``object.method`` (the dot form is itself a bug for a binding). Comments and strings are
    removed; Lua's own libraries (``string.pack`` ...) and the script's own local tables are not
    bindings. A local holding a binding's userdata is named by the LuaLS annotation ArduPilot's
    own scripts use, ``---@type AP_RangeFinder_Backend_ud`` on the line before ``local x = ...``:
    its calls count as calls on that type (``AP_RangeFinder_Backend:get_state``)."""
    typed = {
        var: typ.removesuffix("_ud")
        for typ, var in re.findall(r"---@type\s+([A-Za-z_]\w*)\s*\n\s*local\s+([A-Za-z_]\w*)", source)
    }
    text = re.sub(r"--\[\[.*?\]\]", "", source, flags=re.S)
    text = re.sub(r"--[^\n]*", "", text)
    text = re.sub(r'"(?:\\.|[^"\\])*"|\'(?:\\.|[^\'\\])*\'', '""', text)
    local = set(re.findall(r"\blocal\s+function\s+([A-Za-z_]\w*)", text))
    for names in re.findall(r"\blocal\s+([A-Za-z_]\w*(?:\s*,\s*[A-Za-z_]\w*)*)", text):
        local.update(n.strip() for n in names.split(","))
    calls = set()
    for obj, sep, meth in _BINDING_CALL.findall(text):
        if obj in _LUA_LIBRARIES or (sep == "." and obj in local):
            continue
        calls.add(f"{typed.get(obj, obj)}{sep}{meth}")
    return calls


def _deny_attributes(obj: object, name: str, is_setting: bool) -> str:
    raise AttributeError("the script cannot reach Python objects")


def pack_mavlink_message_t(raw: bytes) -> bytes:
    """A MAVLink 2 frame (as sent on the wire) in the layout of ArduPilot's ``mavlink_message_t``
    that ``mavlink:receive_chan()`` returns: checksum, magic, len, incompat, compat, seq, sysid,
    compid, msgid (uint24), payload zero-filled."""
    if len(raw) >= 8 and raw[0] == 0xFE:  # MAVLink 1: no flags, one-byte message id
        length, seq, sysid, compid, msgid = raw[1:6]
        payload = raw[6 : 6 + length]
        crc = int.from_bytes(raw[6 + length : 8 + length], "little")
        head = struct.pack("<HBBBBBBB", crc, 0xFE, length, 0, 0, seq, sysid, compid)
        return head + msgid.to_bytes(3, "little") + payload.ljust(MAVLINK_MSG_T_PAYLOAD, b"\0")
    if len(raw) < 12 or raw[0] != 0xFD:
        raise ValueError("not a MAVLink frame")
    length, incompat, compat, seq, sysid, compid = raw[1:7]
    msgid = int.from_bytes(raw[7:10], "little")
    payload = raw[10 : 10 + length]
    crc = int.from_bytes(raw[10 + length : 12 + length], "little")
    head = struct.pack("<HBBBBBBB", crc, 0xFD, length, incompat, compat, seq, sysid, compid)
    return head + msgid.to_bytes(3, "little") + payload.ljust(MAVLINK_MSG_T_PAYLOAD, b"\0")


class ScriptHost:
    """One script, loaded and scheduled like ArduPilot's scripting engine."""

    def __init__(self, script: Path, io: VehicleIO) -> None:
        self.io = io
        self.path = Path(script)
        try:
            source = self.path.read_text()
        except OSError as exc:
            raise ScriptError(f"cannot read on-board script {self.path}: {exc}") from None
        self.running = False
        self.error: str | None = None
        self._overrides: dict[int, tuple[int, int]] = {}
        self._queue: deque[tuple[bytes, int, int]] = deque()
        self._queue_len = 0
        self._rx_ids: set[int] = set()
        self._blocked: set[int] = set()
        self._now_ms = io.time_ms()
        self._lua = lua53.LuaRuntime(
            register_eval=False,
            register_builtins=False,
            unpack_returned_tuples=True,
            encoding="latin-1",
            attribute_filter=_deny_attributes,
            max_memory=MEMORY_LIMIT,
        )
        self._guarded = self._lua.execute(_PRELUDE, self._lua.table_from(self._bindings()), INSTRUCTION_LIMIT)
        g = self._lua.globals()
        for name in ("python", "require", "dofile", "loadfile", "load", "io", "os", "debug", "package"):
            g[name] = None
        try:
            # named as ArduPilot's luaL_loadfile names it (SITL's ./scripts/), so error messages
            # read "./scripts/<file>:<line>: ..." as on the autopilot
            chunk = self._lua.compile(source, name=f"@./scripts/{self.path.name}")
        except lua53.LuaSyntaxError as exc:
            raise ScriptError(f"{self.path.name}: {exc}") from None
        limit = ardupilot_load_error(source)  # a limit ArduPilot's Lua has and stock Lua has not
        if limit is not None:
            raise ScriptError(f"{self.path.name}: {limit}")
        self._next: tuple[object, int] | None = None
        self.running = True
        self._call(chunk)

    # -- what the vehicle calls -------------------------------------------------------------
    def run_due(self, now_ms: int) -> None:
        """Run the script's callback if its time has come (one callback per call)."""
        self._now_ms = now_ms
        if self.running and self._next is not None and now_ms >= self._next[1]:
            fn, _ = self._next
            self._call(fn)

    def deliver(self, msg: object, chan: int) -> bool:
        """Queue a received message for ``mavlink:receive_chan()`` if the script registered
        for its id and the queue has room (ArduPilot drops it otherwise)."""
        if not self.running or msg.get_msgId() not in self._rx_ids:  # type: ignore[attr-defined]
            return False
        if len(self._queue) >= self._queue_len:
            return False
        raw = msg.get_msgbuf()  # type: ignore[attr-defined]
        if not raw:
            raise ValueError("deliver() needs a packed or received MAVLink message")
        self._queue.append((pack_mavlink_message_t(bytes(raw)), chan, self._now_ms))
        return True

    def blocks_command(self, command: int) -> bool:
        return self.running and command in self._blocked

    def output_override(self, chan0: int, now_ms: int) -> int | None:
        o = self._overrides.get(chan0)
        if o is None or now_ms >= o[1]:
            return None
        return o[0]

    # -- running the Lua side -----------------------------------------------------------------
    def _call(self, fn: object) -> None:
        try:
            result = self._guarded(fn)  # type: ignore[operator]
        except lua53.LuaError as exc:
            self._stop(str(exc))
            return
        except Exception as exc:  # a binding given arguments it cannot use: a script error in ArduPilot too
            self._stop(f"{type(exc).__name__}: {exc}")
            return
        if isinstance(result, tuple) and len(result) >= 2 and result[0] is not None:
            delay = result[1]
            if not isinstance(delay, int | float) or delay < 0:
                self._stop(f"bad callback delay {delay!r}")
                return
            self._next = (result[0], self._now_ms + int(delay))
        else:
            self._next = None
            self.running = False

    def _stop(self, message: str) -> None:
        self.running = False
        self._next = None
        self.error = message
        self.io.send_text(LUA_ERROR_SEVERITY, f"Lua: {message}"[:50])

    def _bindings(self) -> dict[str, object]:
        io = self.io

        def rf(orientation: int, what: str) -> object:
            r = io.rangefinder(int(orientation))
            if what == "has":
                return r is not None
            if r is None:
                return False if what == "data" else 0
            return {
                "data": r.status == 4,
                "status": r.status,
                "distance": r.distance_m,
                "min": r.min_m,
                "max": r.max_m,
                "quality": r.signal_quality_pct,
                "stamp": r.last_reading_ms,
            }[what]

        def velocity() -> tuple | None:
            v = io.velocity_ned()
            return None if v is None else tuple(float(x) for x in v)

        def mav_init(queue_length: int, num_rx: int) -> None:
            self._queue_len = max(0, int(queue_length))

        def mav_register(msgid: int) -> bool:
            self._rx_ids.add(int(msgid))
            return True

        def mav_block(command: int) -> bool:
            self._blocked.add(int(command))
            return True

        def mav_receive() -> tuple | None:
            if not self._queue:
                return None
            msg, chan, t = self._queue.popleft()
            return msg, chan, t

        def mav_send(chan: int, msgid: int, message: str) -> bool:
            return io.send_mavlink(int(chan), int(msgid), message.encode("latin-1"))

        def set_override(chan: int, pwm: float, timeout_ms: float) -> None:
            self._overrides[int(chan)] = (int(pwm), self._now_ms + int(timeout_ms))

        def get_output(chan: int) -> int:
            o = self.output_override(int(chan), self._now_ms)
            return io.mixer_pwm(int(chan)) if o is None else o

        return {
            "millis": lambda: io.time_ms(),
            "micros": lambda: io.time_us(),
            "send_text": lambda sev, text: io.send_text(int(sev), text),
            "send_named_float": lambda name, value: io.send_named_float(name, float(value)),
            "mav_init": mav_init,
            "mav_register": mav_register,
            "mav_block": mav_block,
            "mav_receive": mav_receive,
            "mav_send": mav_send,
            "set_override": set_override,
            "get_output": get_output,
            "estop": lambda: bool(io.emergency_stop()),
            "accel": lambda instance: io.accel(),
            "gyro": lambda instance: io.gyro(),
            "rf": rf,
            "rf_count": lambda: 1 if io.rangefinder(DOWN) is not None else 0,
            "rf_orient": lambda: DOWN,
            "attitude": lambda: tuple(float(x) for x in io.attitude()),
            "velocity": velocity,
            "is_armed": lambda: bool(io.is_armed()),
            "arm": lambda: bool(io.arm()),
            "disarm": lambda: bool(io.disarm()),
            "get_mode": lambda: io.mode(),
            "set_mode": lambda mode: bool(io.set_mode(int(mode))),
            "set_velocity": lambda n, e, d: bool(io.set_target_velocity_ned(float(n), float(e), float(d))),
            "rc_pwm": lambda chan: io.rc_pwm(int(chan)),
            "param_get": lambda name: io.param(name),
            "param_set": lambda name, value: bool(io.set_param(name, float(value))),
        }
