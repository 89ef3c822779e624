"""The driver as a landing state machine drives it: the real simulated board over a real pty,
timeouts on an injected clock the test advances, writes that never block, reconnection, and the
operation handle."""

from __future__ import annotations

import contextlib
import os
import signal
import time
from pathlib import Path

import pytest
import serial

from slopelander.controller.clock import ManualClock
from slopelander.legs import (
    AngleOutOfRange,
    BoardDisconnected,
    BoardReconnected,
    LegBoard,
    LegNotConverged,
    LegTimeout,
    OperationCancelled,
    OperationPending,
    OperationSuperseded,
    TorqueOutOfRange,
    WriteQueueFull,
    load_calibration,
)
from slopelander.legs.messages import LegState
from tests.legs.conftest import _start, _stop

# Only a bound against a hung test: no driver timeout below depends on the wall clock.
HANG_S = 30.0


def open_on(sim, clock, **kw) -> LegBoard:
    return LegBoard.open(str(sim.link), 115200, timeout=3.0, clock=clock, **kw)


def poll_until(drv: LegBoard, cond, what: str, clock: ManualClock | None = None) -> None:
    """Poll until ``cond``; with ``clock``, advance it as the wall clock goes (so resends run)."""
    end = time.monotonic() + HANG_S
    while not cond():
        drv.poll()
        if time.monotonic() > end:
            pytest.fail(f"never happened: {what}")
        time.sleep(0.005)
        if clock is not None:
            clock.advance(0.005)


@contextlib.contextmanager
def stopped(proc):
    """The board frozen (SIGSTOP): it reads nothing, so the pty fills up. The whole process
    group, since the firmware may run in a MicroPython child that reads the pty itself."""
    os.killpg(proc.pid, signal.SIGSTOP)
    try:
        yield
    finally:
        os.killpg(proc.pid, signal.SIGCONT)


def test_writes_never_block_and_a_full_queue_is_a_typed_error(board):
    clk = ManualClock(100.0)
    with open_on(board, clk, max_queue_bytes=2048) as drv:
        with stopped(board.proc):
            longest, sent, full = 0.0, 0, None
            for _ in range(20000):
                t0 = time.monotonic()
                try:
                    drv.start_loosen()  # loose legs stay loose: only the bytes matter
                    drv.poll()
                except WriteQueueFull as exc:
                    full = exc
                    longest = max(longest, time.monotonic() - t0)
                    break
                longest = max(longest, time.monotonic() - t0)
                sent += 1
            assert full is not None, f"{sent} commands taken without the queue filling"
            assert "not reading" in str(full)
            assert drv.queued_bytes > 0
            assert longest < 0.05  # the old write_timeout stalled a call for 0.5 s here
            t0 = time.monotonic()
            for _ in range(50):  # polling while the port takes nothing does not block either
                drv.poll()
            assert time.monotonic() - t0 < 0.5
        # the board reads again: the queue drains and a new command takes effect. The board
        # answers the backlog's thousands of LOOSENs faster than its line carries the answers
        # and drops some, as a full UART FIFO does; a lost ACK is resent on the driver's clock
        poll_until(drv, lambda: drv.queued_bytes == 0, "queue drained")
        op = drv.start_presets(uphill_nm=1.1, downhill_nm=0.56, timeout=60.0)
        poll_until(drv, lambda: op.done, "legs set", clock=clk)
        assert [round(r.target, 2) for r in op.result().values()] == [1.1, 1.1, 0.56, 0.56]


def test_timeouts_run_on_the_injected_clock(board):
    clk = ManualClock(5.0)
    with open_on(board, clk, silence_timeout=5.0) as drv, board.ctl() as ctl:
        op = drv.start_presets(uphill_nm=2.3, timeout=4.0)
        poll_until(drv, lambda: op.acked, "acknowledged")
        clk.advance(4.01)  # the lead screws need ~10 board seconds: the deadline passes first
        drv.poll()
        assert isinstance(op.exception(), LegNotConverged)
        ctl.inject("silent")
        end = time.monotonic() + 0.5
        while time.monotonic() < end:  # wall time passes, the driver's clock does not
            drv.poll()
            time.sleep(0.01)
        drv.poll()
        clk.advance(5.01)
        with pytest.raises(LegTimeout, match=r"silent: nothing for 5 s"):
            drv.poll()


class KernelBehind(serial.Serial):
    """A real port whose kernel has not yet moved the bytes in flight (its tty worker
    unscheduled, as on a loaded machine): the count of waiting bytes says 0, as TIOCINQ does
    then, while a read, which waits for that worker, gets them."""

    behind = False

    @property
    def in_waiting(self) -> int:
        return 0 if self.behind else super().in_waiting


def test_a_board_whose_bytes_the_kernel_still_holds_is_not_taken_for_silent(board):
    clk = ManualClock(5.0)
    ports: list[KernelBehind] = []

    def port(*args, **kw) -> KernelBehind:
        ports.append(KernelBehind(*args, **kw))
        return ports[-1]

    with open_on(board, clk, silence_timeout=1.0, serial_factory=port) as drv, board.ctl() as ctl:
        poll_until(drv, lambda: drv.status is not None, "a status")
        ports[0].behind = True
        time.sleep(0.3)  # STATUS frames arrive (every 0.1 s); the count does not show them
        clk.advance(0.2)
        drv.catch_up()  # what a companion whose simulator is held for the board does
        assert drv.status.received_at == clk()
        time.sleep(0.3)
        drv.poll()
        clk.advance(1.01)
        drv.poll()  # nothing counted for 1 s: the bytes in flight are read before "silent"
        assert drv.status.received_at == clk()
        # a board that really sent nothing is still silent: nothing in flight to wait for
        ports[0].behind = False
        ctl.inject("silent")
        time.sleep(0.3)
        drv.poll()
        ports[0].behind = True
        clk.advance(1.01)
        t0 = time.monotonic()
        with pytest.raises(LegTimeout, match=r"silent: nothing for 1 s"):
            drv.poll()
        assert time.monotonic() - t0 < 0.5


def test_a_board_whose_hello_reply_the_kernel_still_holds_is_found_at_the_deadline(board):
    """The handshake's last look reads what the kernel has in flight too, as the silence check
    does: a board whose reply a loaded machine held is not refused as silent."""

    def port(*args, **kw) -> KernelBehind:
        ser = KernelBehind(*args, **kw)
        ser.behind = True  # the count says 0 throughout: only a read that waits sees the reply
        return ser

    t0 = time.monotonic()
    with LegBoard.open(str(board.link), 115200, timeout=1.0, serial_factory=port) as drv:
        assert drv.info is not None and drv.info.legs == 4
    assert time.monotonic() - t0 >= 1.0  # found at the last look, not before


def test_a_board_that_comes_back_is_reconnected(sim_board):
    sim = sim_board()
    clk = ManualClock()
    directory = Path(sim.link).parent
    with open_on(sim, clk) as drv:
        first = drv.start_presets(uphill_nm=1.1, timeout=60.0)
        poll_until(drv, lambda: first.acked, "acknowledged")
        with sim.ctl() as ctl:
            ctl.inject("unplug")
        with pytest.raises(BoardDisconnected):
            poll_until(drv, lambda: False, "disconnected")
        assert isinstance(first.exception(), BoardDisconnected)
        _stop(sim.proc)  # the board is power-cycled: a new process on the same port name
        again = _start(directory, (), sim.speed)
        try:
            info = drv.reconnect(timeout=3.0)
            assert info.legs == 4
            assert drv.decoder.rejects.total() == 0
            op = drv.start_presets(uphill_nm=0.56, timeout=60.0)
            poll_until(drv, lambda: op.done, "preset on the new board")
            assert op.exception() is None
            # sequence numbers restarted: HELLO is 0, this preset 1, and the board saw it last
            assert drv.status.last_cmd_seq == 1
        finally:
            _stop(again.proc)


def test_reconnect_drops_running_operations_with_a_typed_error(board):
    clk = ManualClock()
    with open_on(board, clk) as drv:
        op = drv.start_presets(downhill_nm=2.3, timeout=60.0)
        poll_until(drv, lambda: op.acked, "acknowledged")
        drv.reconnect(timeout=3.0)
        assert op.done and isinstance(op.exception(), BoardReconnected)
        with pytest.raises(BoardReconnected):
            op.result()
        assert drv.queued_bytes == 0
        drv.query()  # numbering restarted: HELLO 0, this QUERY 1
        poll_until(drv, lambda: drv.status.last_cmd_seq == 1, "the board saw the QUERY as seq 1")
        assert isinstance(op.exception(), BoardReconnected)  # polling did not revive it


def test_the_operation_handle_is_read_only_superseded_and_cancellable(board):
    clk = ManualClock()
    with open_on(board, clk) as drv:
        old = drv.start_presets(uphill_nm=1.1, timeout=60.0)
        with pytest.raises(OperationPending):
            old.result()
        assert old.exception() is None and not old.done
        for name in ("done", "error", "results", "legs", "deadline"):
            with pytest.raises(AttributeError):
                setattr(old, name, None)
        with pytest.raises(TypeError):
            old.targets[0] = 3.0  # type: ignore[index]
        new = drv.start_presets(uphill_nm=1.7, timeout=60.0)
        assert old.done and isinstance(old.exception(), OperationSuperseded)
        assert "superseded by friction on legs [0, 1]" in str(old.exception())
        other = drv.start_presets(downhill_nm=0.56, timeout=60.0)  # other legs: both run
        assert not new.done and not other.done
        assert other.cancel() is True and other.cancel() is False
        assert other.cancelled and isinstance(other.exception(), OperationCancelled)
        poll_until(drv, lambda: new.done, "the newer preset")
        results = new.result()
        assert sorted(results) == [0, 1]
        assert all(r.achieved == pytest.approx(1.7, abs=0.1) for r in results.values())
        assert new.cancel() is False  # a finished operation stays finished
        assert drv.status.legs[2].state is not LegState.FAULT


def test_a_preset_outside_the_calibration_is_refused_before_anything_is_sent(board):
    cal = load_calibration()
    with pytest.raises(TorqueOutOfRange, match=r"leg 0: 3\.5 N·m is outside"):
        cal.check_preset(1.7, 3.5)
    with pytest.raises(AngleOutOfRange, match=r"leg 0: angle 40 deg is outside the range 0–37\.5"):
        cal.check_preset(1.7, 2.3, uphill_angle_deg=40)
    cal.check_preset(1.7, 2.3, uphill_angle_deg=24.0)
    with open_on(board, ManualClock()) as drv:
        with pytest.raises(TorqueOutOfRange):
            drv.check_preset(3.3, 1.0)
        seen = drv._statuses  # a few reports later the board has still seen only the HELLO (seq 0)
        poll_until(drv, lambda: drv._statuses >= seen + 3, "three reports")
        assert drv.queued_bytes == 0 and drv.status.last_cmd_seq == 0
        assert all(leg.target_ma == 0 for leg in drv.status.legs)
