"""The simulated leg board: the board's firmware on a pseudo-terminal over a plant model.

The firmware is ``firmware/legboard`` (package ``legfw``), the code a real board runs; here
it runs on MicroPython when ``SLOPELANDER_MICROPYTHON`` names one, else on this CPython
(:mod:`slopelander_sitl.legboard.runtime`), with the motor/screw/stack/leg plant behind its HAL.
"""

from slopelander_sitl.legboard.control import BoardControl, ControlError
from slopelander_sitl.legboard.server import BoardServer, FaultSpec

__all__ = ["BoardControl", "BoardServer", "ControlError", "FaultSpec"]
