"""An error in the real script's update (issue 40, finding 3), in real Lua 5.3: ArduPilot stops a
script that raises (lua_scripts::run_next_script), and with it every override; the script now
runs its update under pcall and leaves a defined safe state per state, reported as SL_STATE and
STATUSTEXT. The error is injected into a copy of the script: at the top of each update it raises
while ``SCR_USER1`` (a parameter ArduPilot keeps for scripts) equals the script's state."""

from __future__ import annotations

from pathlib import Path

import pytest
from script_bench import SCRIPT, Bench, TestVehicle
from test_script_reflex import PCT, arm, descend, good, refresh, setup

from slopelander.controller.script_contract import CMD_REFLEX, STILL_S, Reflex, ScriptState

S = ScriptState
ACCEPTED, TEMP_REJECTED, DENIED = 0, 1, 2
STILL_MS = round(STILL_S * 1000)
#: where the error is injected: the first line of the script's update
UPDATE = "local function step()\n  local t = now()\n"
INJECTED = UPDATE + '  if param:get("SCR_USER1") == state then error("injected fault") end\n'


#: the line of the injected error in the copy (the line after the update's first two)
INJECTED_LINE = SCRIPT.read_text().split(UPDATE)[0].count("\n") + 3


def faulty_script(folder: Path) -> Path:
    """The shipped script, raising at the top of its update while SCR_USER1 equals its state."""
    source = SCRIPT.read_text()
    assert source.count(UPDATE) == 1, "the script's update is no longer where the injection goes"
    path = folder / "slopelander.lua"
    path.write_text(source.replace(UPDATE, INJECTED))
    return path


def bench_in(tmp_path: Path, vehicle: TestVehicle | None = None) -> Bench:
    b = Bench(faulty_script(tmp_path), vehicle)
    b.run(50)
    return b


def fail_in(b: Bench, state: int) -> None:
    """Raise from now on while the script is in ``state``."""
    b.io.params["SCR_USER1"] = float(state)


def stall(b: Bench, ms: int) -> None:
    b.io.now_ms += ms


def cut_now(b: Bench, ramp_ms: float = 0) -> None:
    """Armed, down through the cut height: until the motors are cut (CUT, or the fault after it)."""
    b.io.range = good(0.5)
    arm(b, 3000, ramp_ms)
    descend(b, 0.32, 0.5, 150)
    for _ in range(200):
        if b.io.state() in (S.CUT, S.FAULT_HELD):
            break
        b.run(1)
    assert b.io.state() in (S.CUT, S.FAULT_HELD)
    b.io.range = good(0.2)


def impact(b: Bench) -> None:
    b.io.accel_body = (0.0, 0.0, -45.0)
    b.run(5)
    b.io.accel_body = (0.0, 0.0, -9.81)


def test_a_fault_after_the_cut_holds_the_motors_stopped_and_disarms_once_still(tmp_path: Path) -> None:
    """Raised in CUT, falling onto the roof: the script goes on running, holds the motors stopped
    (not the mixer's climb), through a stalled scripting thread too, reports FAULT_HELD and the
    error, never reverses, and disarms the vehicle once it has been still for a second."""
    b = bench_in(tmp_path)
    fail_in(b, S.CUT)
    b.io.velocity = (0.0, 0.0, 0.5)
    cut_now(b)
    b.run(5)
    assert b.host.running, b.host.error
    assert b.io.state() == S.FAULT_HELD and b.outputs() == [1500] * 4
    texts = b.io.sl_texts()
    assert "SL: fault in CUT, motors held stopped" in texts
    said = [t for t in texts if t.startswith("SL: error ")]
    assert said and said[0] == f"SL: error {INJECTED_LINE}: injected fault", texts  # <= 50 characters
    assert not any(t.startswith("Lua: ") for _, _, t in b.io.texts)
    stall(b, 150)
    assert b.outputs() == [1500] * 4  # a stalled scripting thread does not hand them back
    b.run(1)
    b.io.accel_body = (0.0, 0.0, -45.0)  # the impact: no reverse thrust without the reflex
    b.run(5)
    b.io.accel_body = (0.0, 0.0, -9.81)
    b.io.velocity = (0.0, 0.0, 0.0)
    assert b.io.state() == S.FAULT_HELD and b.outputs() == [1500] * 4
    b.run(STILL_MS - 50)
    assert b.io.armed and b.outputs() == [1500] * 4
    states = [v for t, n, v in b.io.named if n == "SL_STATE" and t > b.io.now_ms - 1000]
    assert 4 <= len(states) <= 6 and set(states) == {S.FAULT_HELD}  # announced at 5 Hz
    b.run(100)
    assert not b.io.armed and b.io.state() == S.FAULT and b.outputs() == [None] * 4
    assert "SL: fault: disarmed" in b.io.sl_texts()


def test_a_fault_in_the_reverse_thrust_ramps_it_down_to_a_hold(tmp_path: Path) -> None:
    """The legs, bent under the thrust, spring back when it stops: it ends over the SETUP's ramp."""
    b = bench_in(tmp_path)
    fail_in(b, S.RVT)
    cut_now(b, ramp_ms=400)
    impact(b)
    pwm = []
    for _ in range(600):
        b.run(1)
        pwm.append(b.outputs()[0])
    assert b.io.state() == S.FAULT_HELD and b.host.running
    ramp = [p for p in pwm if p != 1500]
    assert 395 <= len(ramp) <= 410, len(ramp)
    assert ramp[0] <= 1500 - 5 * PCT + 10 and ramp == sorted(ramp) and pwm[-1] == 1500
    assert "SL: fault in RVT, motors held stopped" in b.io.sl_texts()


def test_a_fault_on_the_roof_answers_disarm_and_abort_and_refuses_the_rest(tmp_path: Path) -> None:
    b = bench_in(tmp_path)
    cut_now(b)
    impact(b)
    b.run(400)
    assert b.io.state() == S.HOLD
    fail_in(b, S.HOLD)
    b.run(5)
    assert b.io.state() == S.FAULT_HELD
    refused = ((Reflex.ARM, 0.3, 30, 80, 300, 3000), (Reflex.TAKEOFF_RELEASE, 25), (Reflex.SETUP, 0, 0.5))
    for params in refused:
        ack = b.command(CMD_REFLEX, *params)
        assert ack.result == TEMP_REJECTED and b.io.sl_texts()[-1] == "SL: script fault: reboot to clear"
    assert b.command(CMD_REFLEX, Reflex.ABORT, request=2.5).result == DENIED  # and said why
    assert b.io.sl_texts()[-1] == "SL: bad request number"
    b.io.velocity = (0.2, 0.0, 0.0)  # sliding
    ack = b.command(CMD_REFLEX, Reflex.DISARM)
    assert ack.result == TEMP_REJECTED and b.io.sl_texts()[-1] == "SL: disarm: moving 0.20 m/s"
    b.io.velocity = (0.0, 0.0, 0.0)
    b.run(STILL_MS // 2)
    assert b.io.armed and b.outputs() == [1500] * 4
    assert b.command(CMD_REFLEX, Reflex.DISARM).result == TEMP_REJECTED  # still for only 0.5 s
    b.run(STILL_MS // 2)
    assert not b.io.armed and b.io.state() == S.FAULT  # the script's own, once still for 1 s


def test_the_emergency_stop_releases_a_faulted_hold(tmp_path: Path) -> None:
    b = bench_in(tmp_path)
    fail_in(b, S.CUT)
    cut_now(b)
    b.run(5)
    assert b.io.state() == S.FAULT_HELD
    b.io.estop = True
    b.run(20)
    assert b.io.state() == S.FAULT and b.outputs() == [None] * 4
    assert "SL: fault: motors released (emergency stop)" in b.io.sl_texts()


def test_a_fault_in_the_armed_descent_stops_it_and_climbs(tmp_path: Path) -> None:
    """Issue 40 finding 3: a dead reflex in ARMED let the descent go on for the rest of the last
    ARMED report's validity (and the companion's target for GUID_TIMEOUT)."""
    b = bench_in(tmp_path)
    b.io.range = good(1.0)
    setup(b)
    assert refresh(b).result == ACCEPTED and b.io.state() == S.ARMED
    fail_in(b, S.ARMED)
    b.run(5)
    assert b.io.state() == S.FAULT and b.host.running
    assert "SL: fault in ARMED, climbing" in b.io.sl_texts()
    assert b.io.velocity_targets and b.io.velocity_targets[0][1:] == (0.0, 0.0, -0.5)
    b.io.range = good(0.2)  # the range would have cut: the reflex is gone
    b.run(300)
    assert b.outputs() == [None] * 4
    b.run(2000)
    n = len(b.io.velocity_targets)
    assert 19 <= n <= 21  # the climb lasts its 2 s, then ArduCopter holds after GUID_TIMEOUT
    b.run(500)
    assert len(b.io.velocity_targets) == n


def test_a_fault_before_any_landing_refuses_to_arm(tmp_path: Path) -> None:
    b = bench_in(tmp_path)
    b.io.range = good(1.0)
    fail_in(b, S.IDLE)
    b.run(20)
    assert b.io.state() == S.FAULT and b.host.running
    assert b.command(CMD_REFLEX, Reflex.SETUP, 0, 0.5).result == TEMP_REJECTED
    assert b.io.state() == S.FAULT and not b.io.velocity_targets
    b.run(5000)
    said = [t for t, _, text in b.io.texts if text.startswith("SL: fault in IDLE, ")]
    assert len(said) == 2 and said[1] - said[0] == pytest.approx(5000, abs=15)  # repeated every 5 s


class GyroFails(TestVehicle):
    """A vehicle whose gyro binding fails once ``broken``: the update and the fault's own loop
    both read it (the stillness), so the fault handling itself raises."""

    broken: bool = False

    def gyro(self) -> tuple[float, float, float]:
        if self.broken:
            raise RuntimeError("no gyro")
        return super().gyro()


def test_when_the_fault_handling_itself_raises_the_held_motors_stay_stopped(tmp_path: Path) -> None:
    io = GyroFails()
    b = bench_in(tmp_path, io)
    cut_now(b)
    impact(b)
    b.run(400)
    assert io.state() == S.HOLD
    io.broken = True
    b.run(50)
    assert b.host.running and io.state() == S.FAULT_HELD and b.outputs() == [1500] * 4
    stall(b, 200)
    assert b.outputs() == [1500] * 4
    b.run(1000)
    assert io.state() == S.FAULT_HELD and b.outputs() == [1500] * 4 and io.armed
    io.armed = False  # the pilot's disarm, or the companion's forced one
    b.run(20)
    assert io.state() == S.FAULT and b.outputs() == [None] * 4
