"""Boards the driver must refuse by name before it drives a leg: another protocol version, a
leg count other than four, a calibration made on another board; and a current sense that reads
zero while the motor turns, found by the board and raised as that leg's fault."""

from __future__ import annotations

import os
import threading
import time

import pytest

from slopelander.legs import LegBoard, LegFault, ProtocolError, codec, messages, wire
from slopelander.legs.messages import FaultCode


class FakeBoard:
    """A pty whose other end answers every HELLO with ``reply(seq)`` bytes, from a thread."""

    def __init__(self, reply) -> None:
        self.master, self.slave = os.openpty()
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self._reply = reply
        self._stop = False
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        dec = wire.Decoder()
        while not self._stop:
            try:
                data = os.read(self.master, 4096)
            except (BlockingIOError, OSError):
                time.sleep(0.005)
                continue
            for msg_type, seq, _fields, _raw in dec.feed(data):
                if msg_type == wire.HELLO:
                    os.write(self.master, self._reply(seq))

    def close(self) -> None:
        self._stop = True
        self._thread.join(2.0)
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture
def fake():
    boards = []

    def make(reply) -> FakeBoard:
        boards.append(FakeBoard(reply))
        return boards[-1]

    yield make
    for b in boards:
        b.close()


def test_a_board_of_protocol_version_2_is_named_as_such(fake):
    # version 2's HELLO_REPLY: version, legs, capabilities, max payload, board time (8 bytes)
    old = bytes((2, 4, 3, 64)) + (1234).to_bytes(4, "little")
    board = fake(lambda seq: wire.encode_frame(wire.HELLO_REPLY, seq, old))
    t0 = time.monotonic()
    with pytest.raises(ProtocolError, match="speaks protocol version 2, this driver 3: flash the firmware"):
        LegBoard.open(board.path, timeout=2.0)
    assert time.monotonic() - t0 < 1.5  # at the reply, not at the handshake's timeout


def test_a_board_that_refuses_this_version_says_so(fake):
    nak = wire.pack(wire.NAK, (0, wire.HELLO, wire.NAK_BAD_VERSION))
    board = fake(lambda seq: wire.encode_frame(wire.NAK, 0, wire.pack(wire.NAK, (seq, wire.HELLO, 1))))
    assert len(nak) == 3
    with pytest.raises(ProtocolError, match="does not speak protocol version 3"):
        LegBoard.open(board.path, timeout=2.0)


@pytest.mark.parametrize("legs", [3, 6])
def test_a_board_with_another_leg_count_is_refused(fake, legs):
    reply = messages.HelloReply(wire.PROTOCOL_VERSION, legs, 0, 64, 0, b"12345678", 0x0100)
    board = fake(lambda seq: codec.encode(reply, seq))
    with pytest.raises(ProtocolError, match=f"reports {legs} legs; slopelander drives 4"):
        LegBoard.open(board.path, timeout=2.0)


def test_a_current_sense_dead_at_power_up_is_the_legs_fault(sim_board):
    """The firmware's power-up probe pulls each motor gently: no current where a stalled motor
    draws hundreds of mA is a SENSE fault before any command; a preset on that leg is refused
    with that fault, and nothing moves."""
    board = sim_board("--fault", "sense:3")
    with LegBoard.open(str(board.link), timeout=3.0) as drv:
        assert drv.query().legs[3].fault is FaultCode.SENSE
        with pytest.raises(LegFault) as err:
            drv.set_torques(downhill=2.3, timeout=board.wall(20))
    assert err.value.leg == 3 and err.value.code == FaultCode.SENSE


def test_a_current_sense_that_reads_zero_while_the_motor_turns_is_the_legs_fault(sim_board):
    """The sense dies while the leg clamps: the motor turns (its encoder counts) but the current
    reads zero; the firmware brakes it and reports SENSE before the clamp is near the target."""
    board = sim_board("--fault", "sense:3@3")
    with LegBoard.open(str(board.link), timeout=3.0) as drv:
        with pytest.raises(LegFault) as err:
            drv.set_torques(downhill=2.3, timeout=board.wall(20))
        with board.ctl() as ctl:
            torque = ctl.friction_torques()[3]
    assert err.value.leg == 3 and err.value.code == FaultCode.SENSE
    assert "no current while driven" in str(err.value)
    assert torque < 0.05  # nothing clamped on a leg whose current cannot be read
