"""The script calls only bindings ArduPilot has (names from its scripting documentation)."""

from __future__ import annotations

import re
from pathlib import Path

from slopelander_sitl.vehicle.scripting import binding_calls

SCRIPT = Path(__file__).resolve().parents[2] / "firmware_params" / "scripts" / "slopelander.lua"


def known_bindings(ref: Path) -> set[str]:
    text = (ref / "ardupilot-lua-bindings.txt").read_text()
    out = set()
    for obj, meth in re.findall(r"^function\s+([A-Za-z_0-9]+):([A-Za-z_0-9]+)\s*\(", text, flags=re.M):
        out.add(f"{obj.removesuffix('_ud')}:{meth}")
    return out


def unknown_calls(source: str, ref: Path) -> set[str]:
    return binding_calls(source) - known_bindings(ref)


def test_every_binding_the_script_calls_exists(reference: Path) -> None:
    calls = binding_calls(SCRIPT.read_text())
    assert {"SRV_Channels:set_output_pwm_chan_timeout", "mavlink:receive_chan", "ins:get_accel"} <= calls
    assert unknown_calls(SCRIPT.read_text(), reference) == set()


def test_a_wrong_binding_is_caught(reference: Path) -> None:
    src = SCRIPT.read_text() + "\nSRV_Channels:set_motor_reverse(1)\nlocal s = string.pack('<H', 1)\n"
    assert unknown_calls(src, reference) == {"SRV_Channels:set_motor_reverse"}


def test_comments_and_strings_do_not_count() -> None:
    src = '-- gcs:nonexistent(1)\nlocal s = "arming:fake()"\n--[[ ins:bogus() ]]\ngcs:send_text(6, "x")\n'
    assert binding_calls(src) == {"gcs:send_text"}


def test_a_dot_call_on_a_binding_is_caught_and_local_tables_are_not(reference: Path) -> None:
    src = "local t = {}\nfunction t.f() end\nt.f()\ngcs.send_text(6, 'x')\n"
    assert unknown_calls(src, reference) == {"gcs.send_text"}


def test_the_host_provides_every_binding_the_script_calls() -> None:
    from slopelander_sitl.vehicle.scripting import _PRELUDE

    provided = {
        f"{obj.removesuffix('_ud')}:{meth}"
        for obj, meth in re.findall(r"^function\s+(\w+):(\w+)\s*\(", _PRELUDE, flags=re.M)
    }
    assert binding_calls(SCRIPT.read_text()) <= provided


def test_a_typed_local_counts_as_its_binding_type(reference: Path) -> None:
    """A local holding a binding's userdata is checked by its LuaLS ``---@type`` annotation, as
    ArduPilot's own scripts write it; without one its calls are unknown."""
    typed = "---@type AP_RangeFinder_Backend_ud\nlocal b = rangefinder:get_backend(0)\nb:get_state()\n"
    assert binding_calls(typed) == {"rangefinder:get_backend", "AP_RangeFinder_Backend:get_state"}
    assert unknown_calls(typed, reference) == set()
    wrong = "---@type AP_RangeFinder_Backend_ud\nlocal b = rangefinder:get_backend(0)\nb:last_reading()\n"
    assert unknown_calls(wrong, reference) == {"AP_RangeFinder_Backend:last_reading"}
    untyped = "local b = rangefinder:get_backend(0)\nb:get_state()\n"
    assert unknown_calls(untyped, reference) == {"b:get_state"}
