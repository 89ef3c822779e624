"""The Lua host itself: ArduPilot's scheduling, error and sandbox rules, the mavlink queue."""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink.dialects.v10 import ardupilotmega as mavlink1
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from script_bench import SCRIPT, Bench, TestVehicle

from slopelander_sitl.vehicle.scripting import ScriptError, ScriptHost


def script(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "probe.lua"
    path.write_text(text)
    return path


def texts(io: TestVehicle) -> list[str]:
    return [t for _, _, t in io.texts]


def test_scheduling_by_returned_delay_and_end(tmp_path: Path) -> None:
    io = TestVehicle()
    host = ScriptHost(
        script(
            tmp_path,
            """
local n = 0
local function tick()
  n = n + 1
  gcs:send_text(6, "tick " .. n .. " at " .. millis():toint())
  if n < 3 then return tick, 50 end
end
return tick, 10
""",
        ),
        io,
    )
    for _ in range(200):
        io.now_ms += 1
        host.run_due(io.now_ms)
    assert texts(io) == ["tick 1 at 10", "tick 2 at 60", "tick 3 at 110"]
    assert not host.running and host.error is None


def test_lua_error_stops_the_script_and_is_reported(tmp_path: Path) -> None:
    io = TestVehicle()
    host = ScriptHost(
        script(
            tmp_path,
            """
local function tick()
  SRV_Channels:set_output_pwm_chan_timeout(0, 1500, 30)
  if millis():toint() >= 20 then error("sensor table missing") end
  return tick, 5
end
return tick, 5
""",
        ),
        io,
    )
    for _ in range(100):
        io.now_ms += 1
        host.run_due(io.now_ms)
    assert not host.running
    assert "sensor table missing" in host.error
    assert any(t.startswith("Lua: ") and "sensor table missing" in t for t in texts(io))
    assert host.output_override(0, io.now_ms) is None  # the last override timed out


def test_a_runaway_loop_is_stopped(tmp_path: Path) -> None:
    io = TestVehicle()
    host = ScriptHost(script(tmp_path, "local function f() while true do end end\nreturn f, 1\n"), io)
    io.now_ms = 5
    host.run_due(5)
    assert not host.running
    assert texts(io) == ["Lua: exceeded time allocation"]


def test_a_runaway_loop_is_stopped_even_inside_a_pcall(tmp_path: Path) -> None:
    """ArduPilot's instruction hook (lua_scripts::hook) re-arms itself to fire at every instruction
    once over budget: a script's pcall catches the first error, the next instruction raises
    again, and the script is stopped all the same. A pcall is no way round the budget."""
    io = TestVehicle()
    text = """
local function f()
  local ok = pcall(function() while true do end end)
  gcs:send_text(6, "caught: " .. tostring(ok))
  return f, 1
end
return f, 1
"""
    host = ScriptHost(script(tmp_path, text), io)
    io.now_ms = 5
    host.run_due(5)
    assert not host.running
    assert texts(io) == ["Lua: exceeded time allocation"]


def test_a_binding_given_a_bad_argument_stops_the_script(tmp_path: Path) -> None:
    io = TestVehicle()
    host = ScriptHost(script(tmp_path, 'SRV_Channels:set_output_pwm_chan_timeout(0, "fast", 10)\n'), io)
    assert not host.running
    assert texts(io)[-1].startswith("Lua: ")


def test_no_way_out_to_python(tmp_path: Path) -> None:
    io = TestVehicle()
    ScriptHost(
        script(
            tmp_path,
            """
local names = {"python", "require", "load", "loadfile", "dofile", "io", "os", "debug", "package"}
for _, n in ipairs(names) do
  if _G[n] ~= nil then gcs:send_text(0, "reachable " .. n) end
end
gcs:send_text(6, "done")
""",
        ),
        io,
    )
    assert texts(io) == ["done"]


@pytest.mark.parametrize("text", ["local x = = 1\n", "return function() end, \n"])
def test_a_script_that_does_not_compile_is_a_clear_error(tmp_path: Path, text: str) -> None:
    with pytest.raises(ScriptError, match=r"probe\.lua"):
        ScriptHost(script(tmp_path, text), TestVehicle())


def test_a_missing_script_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(ScriptError, match="cannot read"):
        ScriptHost(tmp_path / "absent.lua", TestVehicle())


def test_only_registered_messages_are_queued_up_to_the_queue_length(bench: Bench) -> None:
    gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    hb = mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)
    hb.pack(gcs)
    assert not bench.host.deliver(hb, 0)
    cmd = mavlink2.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
    cmd.pack(gcs)
    queued = [bench.host.deliver(cmd, 0) for _ in range(10)]
    assert queued == [True] * 8 + [False] * 2  # mavlink:init(8, 1)
    bench.run(20)
    assert bench.host.deliver(cmd, 0)  # the script drained the queue
    assert bench.io.sent == []  # not its command: no ACK from the script


def test_a_mavlink1_command_is_understood(bench: Bench) -> None:
    gcs = mavlink1.MAVLink(None, srcSystem=255, srcComponent=190)
    cmd = mavlink1.MAVLink_command_long_message(1, 1, 31010, 0, 1, 0, 500, 0, 0, 0, 7)  # request 7
    cmd.pack(gcs)
    assert bench.host.deliver(cmd, 0)
    bench.run(20)
    assert bench.outputs() == [1500] * 4


def test_an_unpacked_message_is_refused_clearly(bench: Bench) -> None:
    cmd = mavlink2.MAVLink_command_long_message(1, 1, 31010, 0, 1, 0, 500, 0, 0, 0, 0)
    with pytest.raises(ValueError, match="packed or received"):
        bench.host.deliver(cmd, 0)


def test_a_script_past_ardupilots_100_locals_is_refused_as_ardupilot_refuses_it(tmp_path) -> None:
    """Stock Lua 5.3 takes 200 locals per function, ArduPilot's takes 100 (MAXVARS,
    libraries/AP_Scripting/lua/src/lparser.c; held to the real binary in
    tests/json_physics/test_real_ardupilot.py): the stand-in refuses what the autopilot would."""
    from slopelander_sitl.vehicle.lua_limits import MAXVARS, locals_per_function

    def body(n: int) -> str:
        return "".join(f"local v{i} = {i}\n" for i in range(n)) + "return\n"

    ScriptHost(script(tmp_path, body(100)), TestVehicle())
    with pytest.raises(ScriptError, match=r"too many local variables \(limit is 100\) in main function"):
        ScriptHost(script(tmp_path, body(101)), TestVehicle())
    inner = "local function f()\n" + body(101).replace("return\n", "") + "end\nreturn\n"
    with pytest.raises(ScriptError, match=r"in function at line 1"):
        ScriptHost(script(tmp_path, inner), TestVehicle())
    shipped = max(f.most_at_once for f in locals_per_function(SCRIPT.read_text()))
    assert shipped <= MAXVARS, f"slopelander.lua declares {shipped} locals at once in one function"
