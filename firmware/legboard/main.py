"""The leg board's firmware on the reference board (a Pico): MicroPython runs this at power-up.

Copy this file, the ``legfw`` folder, ``wire.py`` (from ``src/slopelander/legs``) and, if you
override settings, ``config.json`` to the board (docs/legs-build.md, "Flashing").
"""

from legfw.board import run
from legfw.config import Config
from legfw.rp2040 import Rp2040Hal

SAFE_BOOT_PIN = 27  # tied to ground at power-up: the firmware does not start (mpremote can talk)


def main() -> None:
    import machine

    if machine.Pin(SAFE_BOOT_PIN, machine.Pin.IN, machine.Pin.PULL_UP).value() == 0:
        print("leg board: safe boot (GP27 to ground), the firmware is not started")
        return
    # settings the board cannot carry out stop it here, before the watchdog runs: no reboot loop
    cfg = Config.load("config.json", Rp2040Hal.rest_stops)
    # from here an exception brakes every motor, then the watchdog resets the board (board.run)
    run(Rp2040Hal(cfg), cfg)


main()
