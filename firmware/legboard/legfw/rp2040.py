"""The HAL of the reference board: a Raspberry Pi Pico (RP2040) with four DRV8874 drivers.

Pins and parts: docs/legs-build.md. Per leg: a DRV8874 in PH/EN mode (EN = PWM at 20 kHz,
PH = direction; EN low brakes through the low-side switches), its IPROPI current mirror read
by an MCP3204 (12-bit, SPI), the motor's magnetic encoder counted by a PIO state machine, and
the joint's AS5600 magnetic angle sensor behind a TCA9548A I2C multiplexer (the AS5600 has
one fixed address). The companion is on the Pico's USB serial. Written for that board and
checked by MicroPython's compiler on a host; it has not run on one here.
"""

import select
import sys

import machine
import rp2

from legfw.hal import Hal
from legfw.pio import quadrature_x1

EN_PINS = (0, 2, 4, 6)  # PWM slices 0..3, channel A
PH_PINS = (1, 3, 5, 7)
ENCODER_A_PINS = (8, 10, 12, 14)  # B is the next pin
SLEEP_PIN = 22  # nSLEEP of all four drivers: low = every bridge off (pulled low while the Pico resets)
FAULT_PIN = 26  # the drivers' nFAULT outputs, wired together (open drain, pulled up)
SPI_PINS = (18, 19, 16, 17)  # SCK, MOSI, MISO, CS of the MCP3204
I2C_PINS = (20, 21)  # SDA, SCL of the TCA9548A
MUX_ADDR = 0x70
AS5600_ADDR = 0x36
AS5600_ANGLE = 0x0E
PWM_HZ = 20000
WATCHDOG_MS = 500


class Rp2040Hal(Hal):
    """The reference board's hardware (docs/legs-build.md)."""

    def __init__(self, cfg) -> None:
        self.cfg = cfg
        self._sleep = machine.Pin(SLEEP_PIN, machine.Pin.OUT, value=0)
        self._fault = machine.Pin(FAULT_PIN, machine.Pin.IN, machine.Pin.PULL_UP)
        self._en = []
        self._ph = []
        for leg in range(4):
            pwm = machine.PWM(machine.Pin(EN_PINS[leg]))
            pwm.freq(PWM_HZ)
            pwm.duty_u16(0)
            self._en.append(pwm)
            self._ph.append(machine.Pin(PH_PINS[leg], machine.Pin.OUT, value=0))
        self._sign = [1, 1, 1, 1]
        self._sm = []
        for i, a in enumerate(ENCODER_A_PINS):
            pin_a = machine.Pin(a, machine.Pin.IN, machine.Pin.PULL_UP)
            pin_b = machine.Pin(a + 1, machine.Pin.IN, machine.Pin.PULL_UP)
            sm = rp2.StateMachine(i, quadrature_x1, in_base=pin_a, jmp_pin=pin_b)
            sm.exec("set(x, 0)")
            sm.active(1)
            self._sm.append(sm)
        sck, mosi, miso, cs = SPI_PINS
        self._spi = machine.SPI(
            0, 1_000_000, sck=machine.Pin(sck), mosi=machine.Pin(mosi), miso=machine.Pin(miso)
        )
        self._cs = machine.Pin(cs, machine.Pin.OUT, value=1)
        sda, scl = I2C_PINS
        self._i2c = machine.I2C(0, sda=machine.Pin(sda), scl=machine.Pin(scl), freq=400_000)
        self._angle = [3750, 3750, 3750, 3750]
        self._angle_next = 0
        self._rx = bytearray(64)
        self._poll = select.poll()
        self._poll.register(sys.stdin, select.POLLIN)
        self._wdt = machine.WDT(timeout=WATCHDOG_MS)
        import micropython

        micropython.kbd_intr(-1)  # the link is binary: a 0x03 byte must not stop the firmware
        self._sleep.value(1)  # drivers awake, every EN low: braked

    def ticks_ms(self) -> int:
        import time

        return time.ticks_ms()

    def board_id(self) -> bytes:
        return machine.unique_id()[:8]

    def drive(self, leg: int, mv: int) -> None:
        if mv < 0:
            self._ph[leg].value(0)
            self._sign[leg] = -1
            mv = -mv
        elif mv > 0:
            self._ph[leg].value(1)
            self._sign[leg] = 1
        duty = min(65535, mv * 65535 // self.cfg.v_bus_mv)
        self._en[leg].duty_u16(duty)

    def current_ua(self, leg: int) -> int:
        # MCP3204: start bit, single-ended, channel; 12 bits back. IPROPI is the current's
        # magnitude; its sign is the direction the bridge drives
        self._cs.value(0)
        buf = bytearray((0x06, (leg & 3) << 6, 0))
        self._spi.write_readinto(buf, buf)
        self._cs.value(1)
        counts = (buf[1] & 0x0F) << 8 | buf[2]
        uv = counts * self.cfg.adc_ref_mv * 1000 // 4096
        return self._sign[leg] * uv * 1000 // self.cfg.sense_mv_per_a

    def encoder(self, leg: int) -> int:
        sm = self._sm[leg]
        sm.exec("mov(isr, x)")
        sm.exec("push()")
        v = sm.get()
        return v - (1 << 32) if v & 0x80000000 else v

    def angle_cdeg(self, leg: int) -> int:
        # one sensor a tick (each at 62 Hz): the I2C transfers stay short
        if leg == self._angle_next:
            self._angle_next = (leg + 1) % 4
            try:
                self._i2c.writeto(MUX_ADDR, bytes((1 << leg,)))
                raw = self._i2c.readfrom_mem(AS5600_ADDR, AS5600_ANGLE, 2)
                counts = (raw[0] & 0x0F) << 8 | raw[1]
                cdeg = (counts * 36000 // 4096 - self.cfg.angle_zero_cdeg[leg]) % 36000
                self._angle[leg] = cdeg
            except OSError:
                pass  # a missed reading keeps the last one
        return self._angle[leg]

    def rest_stop(self, leg: int, cdeg: int) -> None:
        raise OSError("the reference board has no rest-stop servos (angle_stop must be false)")

    def read_serial(self):
        n = 0
        while n < len(self._rx) and self._poll.poll(0):
            self._rx[n] = sys.stdin.buffer.read(1)[0]
            n += 1
        return bytes(self._rx[:n])

    def write_serial(self, data: bytes) -> None:
        sys.stdout.buffer.write(data)

    def feed_watchdog(self) -> None:
        self._wdt.feed()

    def driver_fault(self) -> bool:
        """A DRV8874 reports over-current, over-temperature or under-voltage."""
        return self._fault.value() == 0
