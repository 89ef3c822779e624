"""The reference board's HAL (legfw/rp2040.py, the encoder's PIO program in legfw/pio.py) and its
main.py, run rather than only compiled: on the real MicroPython (and the HAL on CPython too)
against stand-ins for the Pico's ``machine`` and ``rp2`` modules (tests/legs/fake_pico). Those
fakes are the one thing here that is not the real part: there is no Pico on this machine. They
answer as the parts do (an MCP3204's counts, AS5600 angles, pin levels) and record what the HAL
asked; the PIO program is executed, instruction by instruction, on the encoder's pins."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from slopelander_sitl.legboard.runtime import FIRMWARE_DIR
from tests.legs import micropython_runner
from tests.legs.micropython_runner import needs_micropython

FAKES = Path(__file__).parent / "fake_pico"
WIRE_DIR = micropython_runner.ROOT / "src" / "slopelander" / "legs"

HAL = """
import json
import machine
import rp2
from legfw.board import Firmware
from legfw.config import Config
from legfw.rp2040 import EN_PINS, ENCODER_A_PINS, PH_PINS, Rp2040Hal

for a in ENCODER_A_PINS:  # the encoders' outputs low at power-up
    machine.LEVEL[a] = machine.LEVEL[a + 1] = 0
cfg = Config()
hal = Rp2040Hal(cfg)
out = {"wdt_ms": machine.WDT_STATE["timeout"], "awake": machine.LEVEL[22]}
machine.ADC[0] = 1000
machine.ADC[2] = 4095
hal.drive(0, 1500)
hal.drive(1, 2500)
hal.drive(2, -2500)
hal.drive(3, 9000)
out["current_ua"] = [hal.current_ua(0), hal.current_ua(2)]
out["cs_low"] = machine.SPI_STATE["cs_low"]
out["duty"] = [machine.DUTY[p] for p in EN_PINS]
out["ph"] = [machine.LEVEL[p] for p in PH_PINS]
hal.drive(2, 0)
out["brake"] = [machine.DUTY[EN_PINS[2]], hal.current_ua(2) < 0]
rp2.turn(ENCODER_A_PINS[0], 5)
rp2.turn(ENCODER_A_PINS[3], -3)
out["encoder"] = [hal.encoder(leg) for leg in range(4)]
machine.ANGLE[0], machine.ANGLE[1], machine.ANGLE[2], machine.ANGLE[3] = 0, 1024, 2048, 4095
out["angle_cdeg"] = [hal.angle_cdeg(leg) for leg in range(4)]
fw = Firmware(hal, cfg)
fed = machine.WDT_STATE["feeds"]
for _ in range(25):
    fw.tick()
out["feeds"] = machine.WDT_STATE["feeds"] - fed
print(json.dumps(out))
"""

MAIN = """
import json
import os
import machine
os.chdir({cwd!r})
machine.SPI_STATE["fail_after"] = 20  # the ADC's bus fails in the 5th tick
for ch in range(4):
    machine.ADC[ch] = 150  # about 110 mA: motors that draw current
try:
    import main
    raised = None
except Exception as exc:
    raised = [type(exc).__name__, str(exc)]
print(json.dumps({{
    "raised": raised,
    "wdt_ms": machine.WDT_STATE["timeout"],
    "feeds": machine.WDT_STATE["feeds"],
    "duty_at_fail": machine.SPI_STATE["duty_at_fail"],
    "duty_after": [machine.DUTY.get(p) for p in (0, 2, 4, 6)],
}}))
"""


def interpret(interpreter: str, script: str, cwd: Path | None = None) -> dict:
    """``script`` on MicroPython or CPython with the fakes first on its path; stdin stays open
    (the HAL polls it: the Pico's USB serial never ends), its one printed line."""
    prelude = f"import sys\nsys.path[0:0] = [{str(FAKES)!r}, {str(FIRMWARE_DIR)!r}, {str(WIRE_DIR)!r}]\n"
    if interpreter == "micropython":
        cmd = [micropython_runner.BINARY, "-X", f"heapsize={micropython_runner.HEAP}", "-c", prelude + script]
    else:
        cmd = [sys.executable, "-c", prelude + script]
    proc = subprocess.Popen(
        cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        out, err = proc.stdout.read(), proc.stderr.read()
        proc.wait(60)
    finally:
        proc.stdin.close()
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, (out + err)[-3000:]
    return json.loads(out)


@pytest.fixture(scope="module", params=["cpython", pytest.param("micropython", marks=needs_micropython)])
def hal(request) -> dict:
    return interpret(request.param, HAL)


pytestmark = pytest.mark.xdist_group("legs/micropython_pico_hal")


def test_the_current_sense_scales_adc_counts_to_microamps_signed_as_the_drive(hal: dict) -> None:
    """IPROPI through the carrier's resistor (1.1 V/A) read by a 12-bit ADC on 3.3 V."""
    fwd, rev = hal["current_ua"]
    assert abs(fwd - 1000 / 4096 * 3.3 / 1.1 * 1e6) <= 1
    assert abs(rev + 4095 / 4096 * 3.3 / 1.1 * 1e6) <= 1  # driven backwards: negative
    assert hal["cs_low"]  # each conversion framed by the chip select, with the start bits
    assert hal["brake"][1]  # a brake keeps the sign of the last drive


def test_a_commanded_drive_sets_the_pwm_duty_of_the_supply_and_the_direction(hal: dict) -> None:
    expected = [round(mv / 5000 * 65535) for mv in (1500, 2500, 2500)] + [65535]  # 9 V: full duty
    assert all(abs(d - e) <= 1 for d, e in zip(hal["duty"], expected, strict=True)), hal["duty"]
    assert hal["ph"] == [1, 1, 0, 1]
    assert hal["brake"][0] == 0
    assert hal["awake"] == 1  # the drivers' nSLEEP released once every EN is low


def test_the_encoders_pio_program_counts_forward_up_and_backward_down(hal: dict) -> None:
    assert hal["encoder"] == [5, 0, 0, -3]


def test_the_angle_sensors_are_read_through_the_multiplexer(hal: dict) -> None:
    assert hal["angle_cdeg"] == [0, 9000, 18000, 35991]


def test_every_tick_feeds_the_watchdog(hal: dict) -> None:
    assert hal["wdt_ms"] == 500 and hal["feeds"] == 25


@needs_micropython
def test_main_brakes_every_motor_when_the_firmware_fails_and_leaves_the_reset_to_the_watchdog(
    tmp_path: Path,
) -> None:
    """main.py on MicroPython: at power-up the legs' probe drives every motor; an SPI error in
    the loop brakes them all and ends main (no more feeding: the watchdog resets the Pico)."""
    (tmp_path / "config.json").write_text((FIRMWARE_DIR / "config.json").read_text())
    found = interpret("micropython", MAIN.format(cwd=str(tmp_path)))
    assert found["raised"][0] == "OSError", found
    assert found["wdt_ms"] == 500 and found["feeds"] == 4, found  # fed by the 4 ticks before
    assert all(found["duty_at_fail"]), found
    assert found["duty_after"] == [0, 0, 0, 0], found


@needs_micropython
def test_main_refuses_angle_stop_before_the_watchdog_starts(tmp_path: Path) -> None:
    """A config.json asking for rest-stop servos the reference board does not have: main stops
    at once, naming the setting, with no watchdog running to reboot the board in a loop."""
    (tmp_path / "config.json").write_text(json.dumps({"angle_stop": True}))
    found = interpret("micropython", MAIN.format(cwd=str(tmp_path)))
    kind, text = found["raised"]
    assert kind == "ValueError" and "angle_stop is true" in text, found
    assert found["wdt_ms"] is None and found["duty_after"] == [None] * 4, found
