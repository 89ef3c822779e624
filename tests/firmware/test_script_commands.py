"""The real on-board script in real Lua 5.3: commands, its own COMMAND_ACKs, outputs, refusals."""

from __future__ import annotations

import math

import pytest
from script_bench import Bench

from slopelander.controller.script_contract import CMD_ACTUATOR as ACTUATOR
from slopelander.controller.script_contract import CMD_REFLEX as REFLEX
from slopelander.controller.script_contract import SCRIPT_CONTRACT, Reflex, ScriptState
from slopelander_sitl.vehicle.scripting import RangeReading

ACCEPTED, TEMP_REJECTED, DENIED = 0, 1, 2
ARM = (Reflex.ARM, 0.3, 30, 100, 300, 2000)


def on_the_ground(bench: Bench, d: float = 0.2) -> None:
    """A reading at or below the cut height of an accepted arm: what a commanded reverse needs."""
    bench.io.range = RangeReading(d, 4, 100, 0.1, 3.0)
    assert bench.command(REFLEX, Reflex.SETUP, 500, 0.5).result == ACCEPTED
    assert bench.command(REFLEX, *ARM).result == ACCEPTED
    bench.run(60)


def test_registers_and_blocks_its_commands(bench: Bench) -> None:
    assert bench.host.running, bench.host.error
    assert bench.host.blocks_command(ACTUATOR) and bench.host.blocks_command(REFLEX)
    assert not bench.host.blocks_command(400)
    assert any(t.startswith(f"SL: slopelander script v{SCRIPT_CONTRACT} ") for t in bench.io.sl_texts())


@pytest.mark.parametrize(
    ("action", "pct", "pwm", "state"),
    [(1, 0, 1500, 1), (2, 100, 1000, 2), (2, 50, 1250, 2)],
)
def test_stop_and_reverse_outputs(bench: Bench, action: int, pct: float, pwm: int, state: int) -> None:
    on_the_ground(bench)
    ack = bench.command(ACTUATOR, action, pct, 1000)
    assert ack.get_type() == "COMMAND_ACK"
    assert (ack.command, ack.result) == (ACTUATOR, ACCEPTED)
    assert (ack.target_system, ack.target_component) == (255, 190)
    assert bench.outputs() == [pwm] * 4
    assert bench.io.state() == state


def test_ack_goes_back_on_the_receiving_channel(bench: Bench) -> None:
    ack = bench.command(ACTUATOR, 1, 0, 1000, chan=2)
    assert ack.result == ACCEPTED


def test_release_gives_outputs_back(bench: Bench) -> None:
    bench.command(ACTUATOR, 1, 0, 2000)
    assert bench.outputs() == [1500] * 4
    assert bench.command(ACTUATOR, 0).result == ACCEPTED
    bench.run(40)
    assert bench.outputs() == [None] * 4
    assert bench.io.state() == 0


def test_refused_when_disarmed(bench: Bench) -> None:
    bench.io.armed = False
    refused = ((ACTUATOR, (2, 100, 1000)), (ACTUATOR, (1, 0, 1000)), (REFLEX, ARM))
    for cmd, params in refused:
        ack = bench.command(cmd, *params)
        assert ack.result == TEMP_REJECTED
        assert bench.io.sl_texts()[-1] == "SL: disarmed"
        assert bench.outputs() == [None] * 4
    assert bench.command(ACTUATOR, 0).result == ACCEPTED  # release always accepted


BAD = [
    ((ACTUATOR, (math.nan, 0, 1000)), "unknown action"),
    ((ACTUATOR, (3, 0, 1000)), "unknown action"),
    ((ACTUATOR, (2, math.nan, 1000)), "thrust percent"),
    ((ACTUATOR, (2, 101, 1000)), "thrust percent"),
    ((ACTUATOR, (2, -1, 1000)), "thrust percent"),
    ((ACTUATOR, (2, 50, 10)), "validity"),
    ((ACTUATOR, (2, 50, math.inf)), "validity"),
    ((REFLEX, (9, 0.3, 30, 100, 300, 2000)), "unknown reflex action"),
    ((REFLEX, (1, 0.05, 30, 100, 300, 2000)), "cut height"),
    ((REFLEX, (1, math.nan, 30, 100, 300, 2000)), "cut height"),
    ((REFLEX, (1, 0.3, 4, 100, 300, 2000)), "impact threshold"),
    ((REFLEX, (1, 0.3, 19.5, 100, 300, 2000)), "impact threshold"),  # below 2 g: ~1 g at the cut
    ((REFLEX, (Reflex.SETUP, -1, 0.5)), "reverse ramp"),
    ((REFLEX, (Reflex.SETUP, 500, 0.05)), "descent rate"),
    ((REFLEX, (Reflex.TAKEOFF_RELEASE, 45)), "take-off tilt bound"),
    ((REFLEX, (1, 0.3, 30, 120, 300, 2000)), "thrust percent"),
    ((REFLEX, (1, 0.3, 30, 100, 6000, 2000)), "reverse duration"),
    ((REFLEX, (1, 0.3, 30, 100, 300, 50)), "validity"),
]


@pytest.mark.parametrize(("cmd", "reason"), BAD, ids=[f"{c[0]}-{r}-{i}" for i, (c, r) in enumerate(BAD)])
def test_bad_arguments_denied_outputs_unchanged(bench: Bench, cmd, reason: str) -> None:
    on_the_ground(bench)
    assert bench.command(ACTUATOR, 2, 50, 3000).result == ACCEPTED
    ack = bench.command(cmd[0], *cmd[1])
    assert (ack.command, ack.result) == (cmd[0], DENIED)
    assert bench.io.sl_texts()[-1].startswith("SL: " + reason)
    assert bench.outputs() == [1250] * 4
    assert bench.io.state() == 2


@pytest.mark.parametrize("target", [(2, 1), (1, 50)])
def test_wrong_target_denied(bench: Bench, target) -> None:
    ack = bench.command(ACTUATOR, 2, 100, 1000, target=target)
    assert ack.result == DENIED
    assert bench.io.sl_texts()[-1] == "SL: command for another vehicle"
    assert bench.outputs() == [None] * 4


def test_validity_lapse_gives_outputs_back_to_the_mixer(bench: Bench) -> None:
    on_the_ground(bench)
    bench.command(ACTUATOR, 2, 100, 100, wait_ms=12)  # processed within the 10 ms idle period
    bench.run(80)
    assert bench.outputs() == [1000] * 4
    bench.run(60)  # validity (100 ms) plus the override's own timeout
    assert bench.outputs() == [None] * 4
    assert bench.io.state() == 0
    assert "SL: command validity lapsed" in bench.io.sl_texts()


def test_emergency_stop_wins(bench: Bench) -> None:
    on_the_ground(bench)
    bench.command(ACTUATOR, 2, 100, 3000)
    assert bench.outputs() == [1000] * 4
    bench.io.estop = True
    bench.run(50)
    assert bench.outputs() == [None] * 4
    assert bench.io.state() == 20
    ack = bench.command(ACTUATOR, 1, 0, 1000)
    assert ack.result == TEMP_REJECTED
    assert bench.io.sl_texts()[-1] == "SL: emergency stop"
    assert bench.outputs() == [None] * 4
    bench.io.estop = False
    bench.run(20)
    assert bench.io.state() == 0
    assert bench.outputs() == [None] * 4  # nothing resumes by itself


def test_disarm_returns_to_idle(bench: Bench) -> None:
    bench.command(ACTUATOR, 1, 0, 3000)
    bench.io.armed = False
    bench.run(50)
    assert bench.io.state() == 0
    assert bench.outputs() == [None] * 4


def test_state_announcements(bench: Bench) -> None:
    start = bench.io.now_ms
    bench.run(2000)
    window = [(t, n) for t, n, _ in bench.io.named if t > start]
    states = [t for t, n in window if n == "SL_STATE"]
    versions = [v for t, n, v in bench.io.named if n == "SL_VER" and t > start]
    assert 9 <= len(states) <= 11  # 5 Hz
    assert len(versions) == 2 and set(versions) == {float(SCRIPT_CONTRACT)}  # 1 Hz
    before = len(bench.io.named)
    bench.command(ACTUATOR, 1, 0, 1000, wait_ms=12)
    changes = [(t, v) for t, n, v in bench.io.named[before:] if n == "SL_STATE"]
    assert changes and changes[0][1] == 1  # announced at once on the change


@pytest.mark.parametrize("request_number", [0, -1, 2.5, math.nan, math.inf, 16777216])
def test_a_command_without_a_valid_request_number_is_denied(bench: Bench, request_number) -> None:
    ack = bench.command(ACTUATOR, 1, 0, 1000, request=request_number)
    assert (ack.result, ack.result_param2) == (DENIED, 0)
    assert bench.io.sl_texts()[-1] == "SL: bad request number"
    assert bench.outputs() == [None] * 4


def test_each_ack_echoes_its_own_request_number(bench: Bench) -> None:
    """An old request's ACK cannot be taken for a newer one's: each carries its own number,
    refusals included."""
    on_the_ground(bench)
    assert bench.command(REFLEX, *ARM, request=41).result_param2 == 41
    ack = bench.command(REFLEX, Reflex.DISARM, request=16777215)  # armed, not holding: refused
    assert (ack.result, ack.result_param2) == (TEMP_REJECTED, 16777215)


def test_a_commanded_reverse_needs_the_range_at_or_below_the_cut_height(bench: Bench) -> None:
    """Reverse thrust in the air would drive the vehicle down: a commanded reverse is refused
    unless the newest range sample reads at or below the cut height of the last accepted arm."""
    bench.io.range = RangeReading(1.5, 4, 100, 0.1, 3.0)
    bench.run(60)
    assert bench.command(ACTUATOR, 2, 100, 1000).result == TEMP_REJECTED  # never armed
    assert bench.command(REFLEX, Reflex.SETUP, 500, 0.5).result == ACCEPTED
    assert bench.command(REFLEX, *ARM).result == ACCEPTED
    assert bench.command(ACTUATOR, 2, 100, 1000).result == TEMP_REJECTED  # 1.5 m > 0.3 m
    assert bench.io.sl_texts()[-1] == "SL: reverse: range above the cut height"
    assert bench.outputs() == [None] * 4
    bench.io.range = RangeReading(0.25, 4, 100, 0.1, 3.0)
    bench.run(60)
    assert bench.command(ACTUATOR, 2, 100, 1000).result == ACCEPTED
    assert bench.outputs() == [1000] * 4 and bench.io.state() == ScriptState.REVERSE
