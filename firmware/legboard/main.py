"""The leg board's firmware on the reference board (a Pico): MicroPython runs this at power-up.

Copy this file, the ``legfw`` folder, ``wire.py`` (from ``src/slopelander/legs``) and, if you
override settings, ``config.json`` to the board (docs/legs-build.md, "Flashing").
"""

import time

from legfw.board import Firmware
from legfw.config import Config
from legfw.rp2040 import Rp2040Hal


def load_config() -> Config:
    try:
        return Config.from_json("config.json")
    except OSError:  # no config.json: the reference build's defaults
        return Config()


SAFE_BOOT_PIN = 27  # tied to ground at power-up: the firmware does not start (mpremote can talk)


def main() -> None:
    import machine

    if machine.Pin(SAFE_BOOT_PIN, machine.Pin.IN, machine.Pin.PULL_UP).value() == 0:
        print("leg board: safe boot (GP27 to ground), the firmware is not started")
        return
    cfg = load_config()
    hal = Rp2040Hal(cfg)
    fw = Firmware(hal, cfg)
    due = time.ticks_add(time.ticks_ms(), cfg.tick_ms)
    while True:
        fw.poll_serial()
        late = time.ticks_diff(time.ticks_ms(), due)
        if late >= 0:
            # a tick is due: run it; a loop that fell behind by more than 10 ticks drops them
            # rather than running a burst (board time then lags the wall, as a stalled host's does)
            fw.tick()
            due = time.ticks_add(due, cfg.tick_ms)
            if late > 10 * cfg.tick_ms:
                due = time.ticks_add(time.ticks_ms(), cfg.tick_ms)
        if hal.driver_fault():  # a driver shut its bridge down: brake all, fault the legs that drive
            for leg in fw.legs:
                if leg.state in (1, 2, 3, 5):
                    leg._fail(1)


main()
