"""The HAL on a host: the plant model for motors and sensors, a file descriptor for the serial
link (the board's end of the line the host's CPython launcher relays to a pseudo-terminal).

Link faults a test injects act here, between the firmware and the line: ``silent`` (bytes
the firmware writes are dropped), ``corrupt`` (each byte replaced with a probability) and
``unplug`` (the descriptor closed).
"""

try:
    import os

    _os_read = os.read
    _os_write = os.write
    _os_close = os.close
except (ImportError, AttributeError):  # MicroPython's os has no read/write: use a file object
    _os_read = None

from legfw.compat import wire
from legfw.hal import Hal

READ_CHUNK = 256


class Port:
    """A non-blocking serial descriptor, read and written without ever waiting."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self._file = None if _os_read is not None else open(fd, "r+b")  # noqa: SIM115
        self.dropped = 0

    def fileno(self) -> int:
        return self.fd

    def read(self) -> bytes:
        # a few frames at a time, as a board's UART loop reads: a burst of kilobytes in one
        # buffer fragments a small heap (MemoryError on MicroPython with 192 KB)
        try:
            if self._file is None:
                return _os_read(self.fd, READ_CHUNK)
            return self._file.read(READ_CHUNK) or b""
        except OSError:
            return b""  # nothing there (EAGAIN) or nobody on the other side (EIO)

    def write(self, data: bytes) -> None:
        try:
            n = _os_write(self.fd, data) if self._file is None else self._file.write(data)
        except OSError:
            n = 0
        self.dropped += len(data) - (n or 0)

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
        else:
            _os_close(self.fd)


class SimHal(Hal):
    """The firmware's hardware, simulated: ``plant`` for the legs, ``port`` for the link."""

    rest_stops = True  # the plant moves a leg's rest stop as a servo would

    def __init__(self, plant, port, board_id: bytes, capabilities: int, noise) -> None:
        self.plant = plant
        self.port = port
        self._board_id = board_id
        self.extra_capabilities = capabilities
        self.ms = 0
        self.silent = False
        self.corrupt_rate = 0.0
        self._noise = noise  # for corruption, apart from the plant's sensor noise
        self.watchdog_fed = 0

    def ticks_ms(self) -> int:
        return self.ms

    def board_id(self) -> bytes:
        return self._board_id

    def drive(self, leg: int, mv: int) -> None:
        self.plant.legs[leg].volts = mv / 1000.0

    def current_ua(self, leg: int) -> int:
        return self.plant.sensed_current_ua(leg)

    def encoder(self, leg: int) -> int:
        return self.plant.encoder(leg)

    def angle_cdeg(self, leg: int) -> int:
        return self.plant.angle_cdeg(leg)

    def rest_stop(self, leg: int, cdeg: int) -> None:
        self.plant.legs[leg].stop_deg = cdeg / 100.0

    def read_serial(self):
        return b"" if self.port is None else self.port.read()

    def write_serial(self, data: bytes) -> None:
        if self.port is None or self.silent:
            return
        if self.corrupt_rate > 0.0:
            buf = bytearray(data)
            for i in range(len(buf)):
                if self._noise.uniform() < self.corrupt_rate:
                    buf[i] = int(self._noise.uniform() * 256) & 0xFF
            data = bytes(buf)
        self.port.write(data)

    def feed_watchdog(self) -> None:
        self.watchdog_fed += 1

    def unplug(self) -> None:
        if self.port is not None:
            self.port.close()
            self.port = None


CAPABILITIES = wire.CAP_SIMULATED
