"""A stand-in for MicroPython's ``machine`` on a Pico, for the tests only: there is no Pico here.
It records what the reference board's HAL (firmware/legboard/legfw/rp2040.py) asks of the
hardware and answers as the parts do: levels of pins, PWM duty per pin, an MCP3204 on SPI
(12-bit counts per channel from ``ADC``), AS5600 angle sensors behind a TCA9548A on I2C
(counts per leg from ``ANGLE``), a watchdog that counts its feeds. Runs on MicroPython and
CPython."""

LEVEL = {}  # pin number -> level (what an input reads, what an output was set to)
DUTY = {}  # EN pin number -> duty_u16
ADC = [0, 0, 0, 0]  # MCP3204 counts per channel (the legs' IPROPI)
ANGLE = [0, 0, 0, 0]  # AS5600 raw counts per multiplexer channel
WDT_STATE = {"timeout": None, "feeds": 0}
SPI_STATE = {"transfers": 0, "fail_after": -1, "duty_at_fail": None, "cs_low": True}


class Pin:
    IN = 0
    OUT = 1
    PULL_UP = 1

    def __init__(self, id, mode=-1, pull=-1, value=None):
        self.id = id
        if value is not None:
            LEVEL[id] = value

    def value(self, v=None):
        if v is None:
            return LEVEL.get(self.id, 1)  # pulled up unless a test says otherwise
        LEVEL[self.id] = v
        return None


class PWM:
    def __init__(self, pin):
        self.pin = pin.id
        self.hz = 0

    def freq(self, hz):
        self.hz = hz

    def duty_u16(self, duty):
        assert 0 <= duty <= 65535, duty
        DUTY[self.pin] = duty


class SPI:
    """The MCP3204 behind CS (pin 17): start bit and single-ended in the first byte, the channel
    in the top bits of the second, the 12-bit result in the low nibble of the second and the third."""

    def __init__(self, id, baudrate, sck=None, mosi=None, miso=None):
        self.id = id

    def write_readinto(self, wbuf, rbuf):
        SPI_STATE["transfers"] += 1
        if SPI_STATE["transfers"] == SPI_STATE["fail_after"]:
            SPI_STATE["duty_at_fail"] = [DUTY.get(p, 0) for p in (0, 2, 4, 6)]
            raise OSError(5)  # a bus that failed
        if LEVEL.get(17) != 0 or wbuf[0] != 0x06:
            SPI_STATE["cs_low"] = False
        counts = ADC[wbuf[1] >> 6]
        rbuf[0] = 0
        rbuf[1] = (counts >> 8) & 0x0F
        rbuf[2] = counts & 0xFF


class I2C:
    def __init__(self, id, sda=None, scl=None, freq=0):
        self.channel = None

    def writeto(self, addr, buf):
        assert addr == 0x70  # the TCA9548A: one bit a channel
        self.channel = {1: 0, 2: 1, 4: 2, 8: 3}[buf[0]]

    def readfrom_mem(self, addr, reg, n):
        assert addr == 0x36 and reg == 0x0E and n == 2  # the AS5600's ANGLE register
        counts = ANGLE[self.channel]
        return bytes(((counts >> 8) & 0x0F, counts & 0xFF))


class WDT:
    def __init__(self, timeout=0):
        WDT_STATE["timeout"] = timeout

    def feed(self):
        WDT_STATE["feeds"] += 1


def unique_id():
    return b"\xe6\x61\x41\x03\xe7\x45\x2d\x2f"
