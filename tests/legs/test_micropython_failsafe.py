"""The firmware's main loop when it fails: an exception anywhere brakes every motor before it
propagates (the H-bridges are not left at their last PWM until the watchdog bites), the watchdog
is fed once a tick and no longer once the loop has raised or stalls, and a setting the board
cannot carry out is refused at load. The same scenario runs on the host HAL (SimHal over its
plant) under CPython and under the real MicroPython."""

from __future__ import annotations

import itertools
import json
import sys

import pytest

from slopelander_sitl.legboard.runtime import FIRMWARE_DIR
from tests.legs.micropython_runner import needs_micropython, run

#: its tests share one run per interpreter: one worker (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("legs/micropython_failsafe")

# the main loop (legfw.board.run) on SimHal, with a clock of its own; printed as one JSON line
SCENARIO = """
import json
from legfw.board import run
from legfw.compat import wire
from legfw.config import Config
from legfw.plant import Noise, Plant, PlantParams
from legfw.simhal import SimHal


class Done(Exception):
    pass


class Bench(SimHal):
    # SimHal on a clock that moves 1 ms per reading (the plant stepped every tick), the
    # companion's bytes scripted (HELLO, then a clamp of every leg), and at fail_ms a HAL read
    # that raises (a bus that failed), or at stall_ms a serial read that holds the loop stall_len ms
    def __init__(self, fail_ms=-1, stall_ms=-1, stall_len=0, end_ms=10**9):
        SimHal.__init__(self, Plant(PlantParams(), 0), None, b"SIMBOARD", 0, Noise(1))
        hello = wire.encode_frame(wire.HELLO, 0, wire.pack(wire.HELLO, (wire.PROTOCOL_VERSION, 100)))
        clamp = wire.pack(wire.SET_FRICTION, (15, (100, 100, 100, 100)))
        self.inbox = [hello, wire.encode_frame(wire.SET_FRICTION, 1, clamp)]
        self.fail_ms, self.stall_ms, self.stall_len, self.end_ms = fail_ms, stall_ms, stall_len, end_ms
        self.fed = []
        self.volts_at_fault = None

    def ticks_ms(self):
        self.ms += 1
        if self.ms % 4 == 0:
            self.plant.step(0.004)
        if self.ms >= self.end_ms:
            raise Done()
        return self.ms

    def read_serial(self):
        if 0 <= self.stall_ms <= self.ms:
            self.stall_ms = -1
            self.ms += self.stall_len  # a read that blocked: nothing else runs meanwhile
        return self.inbox.pop(0) if self.inbox and self.ms > 100 else b""

    def encoder(self, leg):
        if 0 <= self.fail_ms <= self.ms:
            self.volts_at_fault = [lg.volts for lg in self.plant.legs]
            raise OSError(5)
        return SimHal.encoder(self, leg)

    def feed_watchdog(self):
        self.fed.append(self.ms)


def loop(hal):
    try:
        run(hal, Config())
    except Exception as exc:
        return type(exc).__name__
    return None


failed = Bench(fail_ms=1500)
raised = loop(failed)
stalled = Bench(stall_ms=1000, stall_len=2000, end_ms=4000)
ended = loop(stalled)

path = "{config}"
with open(path, "w") as f:
    f.write(json.dumps({{"angle_stop": True}}))
refused = None
try:
    Config.load(path, False)
except ValueError as exc:
    refused = str(exc)
print(json.dumps({{
    "raised": raised,
    "volts_at_fault": failed.volts_at_fault,
    "volts_after": [lg.volts for lg in failed.plant.legs],
    "fed": failed.fed,
    "stalled": [ended, stalled.fed, [lg.volts for lg in stalled.plant.legs]],
    "refused": refused,
    "with_servos": Config.load(path, True).angle_stop,
    "shipped": Config.load("{shipped}", False).angle_stop,
}}))
"""


@pytest.fixture(scope="module", params=["cpython", pytest.param("micropython", marks=needs_micropython)])
def outcome(request, tmp_path_factory) -> dict:
    """The scenario's findings on one interpreter."""
    script = SCENARIO.format(
        config=tmp_path_factory.mktemp("cfg") / "config.json", shipped=FIRMWARE_DIR / "config.json"
    )
    if request.param == "micropython":
        (found,) = run(script)
        return found
    printed: list[str] = []
    sys.path.insert(0, str(FIRMWARE_DIR))
    exec(script, {"print": printed.append})
    return json.loads(printed[0])


def test_an_exception_in_the_main_loop_brakes_every_motor_before_it_propagates(outcome: dict) -> None:
    assert outcome["raised"] == "OSError"  # raised again: the board's reset follows
    assert outcome["volts_at_fault"] == [3.0, 3.0, 3.0, 3.0]  # every leg was clamping at full drive
    assert outcome["volts_after"] == [0.0, 0.0, 0.0, 0.0]


def test_the_watchdog_is_fed_every_tick_until_the_loop_raises(outcome: dict) -> None:
    fed = outcome["fed"]
    assert len(fed) > 300 and all(b - a == 4 for a, b in itertools.pairwise(fed))
    assert 1500 - 4 <= fed[-1] < 1500  # the tick that raised fed nothing, nor anything after it


def test_the_watchdog_goes_unfed_while_the_loop_stalls(outcome: dict) -> None:
    """Fed from the loop's tick alone (not a timer that would keep a hung loop alive): a loop held
    2 s leaves the Pico's 500 ms watchdog unfed; the loop then goes on, dropping the lost ticks."""
    ended, fed, volts = outcome["stalled"]
    gaps = [b - a for a, b in itertools.pairwise(fed)]
    stalls = [g for g in gaps if g >= 2000]
    assert len(stalls) == 1 and all(g in (4, 5) for g in gaps if g < 2000), gaps  # 5: the re-sync
    assert fed[-1] > 3900  # fed again once the loop ran again
    assert ended == "Done" and volts == [0.0, 0.0, 0.0, 0.0]  # the end of the loop brakes too


def test_angle_stop_on_a_board_without_rest_stop_servos_is_refused_at_load(outcome: dict) -> None:
    assert "setting angle_stop is true, but this board has no rest-stop servos" in outcome["refused"]
    assert outcome["with_servos"] is True  # the simulated board has them
    assert outcome["shipped"] is False  # the shipped config.json loads on the Pico
