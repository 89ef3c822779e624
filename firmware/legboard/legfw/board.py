"""The firmware's protocol side and scheduler: commands in, STATUS out, four legs ticked.

Board time is the number of ticks run times the tick (ms): the legs, the STATUS period and
the companion's silence all count on it, on the board and on a host that feeds it time.
Frames are parsed by ``wire``, the module the companion's driver uses.
"""

from legfw import FIRMWARE_VERSION
from legfw.compat import ticks_add, ticks_diff, wire
from legfw.leg import Leg

_DRIVEN = (wire.TIGHTENING, wire.HOLDING, wire.LOOSENING, wire.POSITIONING)


def run(hal, cfg) -> None:
    """The board's main loop, forever: serial bytes whenever they come, a tick every
    ``cfg.tick_ms`` (which feeds the watchdog). Any exception (a bug, a bus that failed) brakes
    every motor (``hal.all_off``) and is raised again: the loop, and so the feeding, has ended,
    and the watchdog resets the board; no bridge is left at its last PWM meanwhile."""
    try:
        fw = Firmware(hal, cfg)
        due = ticks_add(hal.ticks_ms(), cfg.tick_ms)
        while True:
            fw.poll_serial()
            late = ticks_diff(hal.ticks_ms(), due)
            if late >= 0:
                # a tick is due: run it; a loop that fell behind by more than 10 ticks drops them
                # rather than running a burst (board time then lags the wall, as a stalled host's does)
                fw.tick()
                due = ticks_add(due, cfg.tick_ms)
                if late > 10 * cfg.tick_ms:
                    due = ticks_add(hal.ticks_ms(), cfg.tick_ms)
            if hal.driver_fault():  # a driver shut its bridge down: fault the legs that drive
                for leg in fw.legs:
                    if leg.state in _DRIVEN:
                        leg._fail(wire.FAULT_OVERCURRENT)
    except BaseException as exc:  # whatever it was, the motors first
        try:  # noqa: SIM105 - MicroPython has no contextlib
            hal.all_off()
        except BaseException:  # a HAL too broken to brake: the watchdog's reset is what is left
            pass
        raise exc


class Firmware:
    """One leg board: :meth:`poll_serial` whenever bytes may have come, :meth:`tick` every
    ``cfg.tick_ms`` of board time."""

    def __init__(self, hal, cfg) -> None:
        self.hal = hal
        self.cfg = cfg
        self.legs = [Leg(i, cfg, hal) for i in range(wire.N_LEGS)]
        self.decoder = wire.Decoder()
        self.ms = 0
        self.seq = 0
        self.hello = False
        self.period_ms = cfg.status_ms
        self.next_status = 0
        self.last_cmd_seq = 0
        self.last_heard_ms = 0
        self.capabilities = (wire.CAP_ANGLE_STOP if cfg.angle_stop else 0) | hal.extra_capabilities
        self.flags = wire.STATUS_FLAG_SIMULATED if hal.extra_capabilities & wire.CAP_SIMULATED else 0
        self.board_id = hal.board_id()

    # ---- time -------------------------------------------------------------------------
    def tick(self) -> None:
        """One period: every leg, the companion-silence rule, a STATUS if one is due."""
        dt = self.cfg.tick_ms
        self.ms += dt
        for leg in self.legs:
            leg.tick(dt)
        if self.hello and self.ms - self.last_heard_ms >= self.cfg.silence_ms:
            # the companion is silent: no leg keeps driving its motor unwatched; a clamp
            # reached stays (the screw self-locks), a motion under way ends as it would
            for leg in self.legs:
                if leg.state == wire.HOLDING:
                    leg.stop()
        self.status_due()
        self.hal.feed_watchdog()

    def status_due(self) -> None:
        if self.hello and self.ms >= self.next_status:
            self.next_status = self.ms + self.period_ms
            self.send_status()

    # ---- the serial link --------------------------------------------------------------
    def poll_serial(self) -> None:
        data = self.hal.read_serial()
        if data:
            for msg_type, seq, fields, _raw in self.decoder.feed(data):
                self.handle(msg_type, seq, fields)
            self.status_due()

    def send(self, msg_type: int, fields: tuple) -> None:
        self.hal.write_serial(wire.encode_frame(msg_type, self.seq, wire.pack(msg_type, fields)))
        self.seq = (self.seq + 1) & 0xFF

    def send_status(self) -> None:
        reports = tuple(leg.report() for leg in self.legs)
        self.send(wire.STATUS, (self.ms & 0xFFFFFFFF, self.last_cmd_seq, self.flags, reports))

    def handle(self, t: int, seq: int, f: tuple) -> None:
        if t >= 0x80:
            return  # a board message echoed back: not for us
        self.last_heard_ms = self.ms
        if t == wire.HELLO:
            if f[0] != wire.PROTOCOL_VERSION:
                self.send(wire.NAK, (seq, t, wire.NAK_BAD_VERSION))
                return
            self.hello = True
            self.period_ms = f[1] or self.cfg.status_ms
            self.next_status = self.ms
            reply = (
                wire.PROTOCOL_VERSION,
                wire.N_LEGS,
                self.capabilities,
                wire.MAX_PAYLOAD,
                self.ms & 0xFFFFFFFF,
                self.board_id,
                FIRMWARE_VERSION,
            )
            self.send(wire.HELLO_REPLY, reply)
            return
        if not self.hello:
            self.send(wire.NAK, (seq, t, wire.NAK_NO_HELLO))
            return
        if t == wire.KEEPALIVE:
            return
        self.last_cmd_seq = seq
        if t == wire.QUERY:
            self.send_status()
            return
        nak = self.apply(t, f)
        if nak:
            self.send(wire.NAK, (seq, t, nak))
        else:
            self.send(wire.ACK, (seq, t))

    def apply(self, t: int, f: tuple):
        """Carry out a command on the legs of its mask; the NAK code if it is refused (then
        no leg changed), else None."""
        legs = [self.legs[i] for i in wire.legs_in(f[0])]
        if t == wire.SET_ANGLE and not self.capabilities & wire.CAP_ANGLE_STOP:
            return wire.NAK_UNSUPPORTED
        if t == wire.SET_FRICTION or t == wire.SET_ANGLE:
            for leg in legs:
                if leg.state == wire.FAULT:
                    return wire.NAK_FAULTED
        if t == wire.SET_FRICTION:
            for leg in legs:
                if f[1][leg.index] > self.cfg.max_target_ma:
                    return wire.NAK_ABOVE_LIMIT
            for leg in legs:
                leg.set_friction(f[1][leg.index])
        elif t == wire.SET_ANGLE:
            for leg in legs:
                leg.set_angle(f[1][leg.index])
        elif t == wire.LOOSEN:
            for leg in legs:
                leg.loosen()
        elif t == wire.STOP:
            for leg in legs:
                leg.stop()
        return None
