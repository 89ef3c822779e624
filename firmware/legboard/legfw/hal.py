"""What the firmware needs of a board, and nothing else.

A HAL (hardware abstraction layer) is one object with these methods. ``rp2040.Rp2040Hal`` is
the reference board; ``simhal.SimHal`` drives a plant model on a host. The firmware calls
them once per tick per leg, so they must not block.
"""


class Hal:
    """The interface (methods raise until a board implements them)."""

    #: capability bits this board adds to ANGLE_STOP (the simulated board sets SIMULATED)
    extra_capabilities = 0
    #: whether the board has rest-stop servos, so that ``angle_stop`` may be set (Config.load)
    rest_stops = False

    def ticks_ms(self) -> int:
        """Milliseconds since power-up (wraps as the board's counter does)."""
        raise NotImplementedError

    def board_id(self) -> bytes:
        """8 bytes that name this board for as long as it exists (the RP2040's flash id)."""
        raise NotImplementedError

    def drive(self, leg: int, mv: int) -> None:
        """Drive a motor at ``mv`` millivolts (sign = direction; 0 = brake, both low sides on)."""
        raise NotImplementedError

    def current_ua(self, leg: int) -> int:
        """The motor current now, µA, signed as the drive (the H-bridge's current mirror)."""
        raise NotImplementedError

    def encoder(self, leg: int) -> int:
        """The motor encoder's count (signed, forward = tightening)."""
        raise NotImplementedError

    def angle_cdeg(self, leg: int) -> int:
        """The leg joint's angle, centidegrees (0 = folded, 3750 = fully extended)."""
        raise NotImplementedError

    def rest_stop(self, leg: int, cdeg: int) -> None:
        """Move the leg's rest stop to ``cdeg`` (boards with the ANGLE_STOP capability)."""
        raise NotImplementedError

    def read_serial(self):
        """Bytes the companion sent since the last call (``b""`` if none); never blocks."""
        raise NotImplementedError

    def write_serial(self, data: bytes) -> None:
        """Queue ``data`` to the companion; never blocks (bytes that do not fit are dropped)."""
        raise NotImplementedError

    def feed_watchdog(self) -> None:
        """Tell the hardware watchdog the main loop is alive."""
        raise NotImplementedError

    def driver_fault(self) -> bool:
        """Whether a motor driver has shut its bridge down (over-current, heat, low supply)."""
        return False

    def all_off(self) -> None:
        """Every motor braked; called on a fault of the firmware itself (``board.run``)."""
        for leg in range(4):
            self.drive(leg, 0)
