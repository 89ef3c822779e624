"""The simulated board's serial line: the pseudo-terminal's master side, relayed to the firmware
over a socket pair by two threads of its own.

Why not hand the firmware the master side itself: Linux moves a pty's bytes from the writer to
the reader in a kernel worker (``flush_to_ldisc`` on the ``events_unbound`` workqueue), and a
poll or read that finds nothing waiting first waits for that worker to finish
(``n_tty_poll`` / ``n_tty_read`` -> ``tty_buffer_flush_work``, drivers/tty/n_tty.c). On a loaded
machine the worker can go unscheduled for a long time: with two busy processes on 2 cores
(kernel 6.18) the firmware's poll of the master side waited 0.2-2.8 s (wchan ``__flush_work``,
2026-12-07). The firmware's one loop also answers the vehicle's clock (``advance``), so the
simulated vehicle stopped with it, ArduCopter stopped sending, and the companion, reading its
link all the while, declared it lost. A real board's UART has no such wait: late bytes are only
late. Here the waits happen in the relay's threads; the firmware reads and writes a socket,
which never waits on the tty layer, and answers the clock at once.

What the line does that a UART does: bytes in order both ways; a small buffer each way (a
firmware that writes faster than the companion reads finds it full and drops, as a board's
full FIFO does); the firmware closing its end (an unplug) closes the master side, which the
companion sees as the device gone. And one thing a test asks of it: :meth:`PtyLine.stall`
holds the bytes both ways for a while, as the loaded kernel did, so that the companion's
handling of a late board can be flown on an idle machine.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import time

CHUNK = 4096
#: wall seconds between tries to write to a full master side
FULL_WAIT_S = 0.001
#: each direction's socket buffer (the kernel doubles it and counts its own overhead)
BUFFER_BYTES = 32768
#: wall seconds between the master reader's looks at whether the line is closing
LOOK_S = 0.05


class PtyLine:
    """Relay the pty master ``master`` to a socket pair; :meth:`board_end` is the firmware's."""

    def __init__(self, master: int) -> None:
        self.master = master
        os.set_blocking(master, False)
        mine, theirs = socket.socketpair()
        # a UART's few bytes of buffer, not a socket's hundreds of kilobytes: a firmware that
        # writes faster than the companion reads drops its newest bytes at once, as a board
        # does, instead of queueing seconds of old STATUS ahead of the next acknowledgement
        theirs.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, BUFFER_BYTES)
        mine.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, BUFFER_BYTES)
        self._sock = mine
        self._board_fd: int | None = theirs.detach()
        os.set_blocking(self._board_fd, False)
        self._stalled_until = 0.0  # monotonic time before which no byte moves (stall)
        self._closing = threading.Event()
        self._to_board = threading.Thread(target=self._master_to_board, name="legboard-line-in", daemon=True)
        self._to_master = threading.Thread(
            target=self._board_to_master, name="legboard-line-out", daemon=True
        )
        self._to_board.start()
        self._to_master.start()

    def board_end(self) -> int:
        """The firmware's descriptor (non-blocking); whoever takes it closes it (an unplug)."""
        fd, self._board_fd = self._board_fd, None
        if fd is None:
            raise RuntimeError("the board's end of the line was already taken")
        return fd

    def _master_to_board(self) -> None:
        """The companion's bytes to the firmware. Owns the master side: closes it when the line
        closes (so no other thread closes a descriptor this one may be polling)."""
        try:
            while not self._closing.is_set():
                try:
                    ready, _, _ = select.select([self.master], [], [], LOOK_S)
                    data = os.read(self.master, CHUNK) if ready else b""
                except BlockingIOError:
                    continue
                except OSError:  # EIO: nobody holds the other side any more
                    self._closing.wait(LOOK_S)
                    continue
                if data:
                    self._wait_stall()
                    try:
                        self._sock.sendall(data)
                    except OSError:  # the firmware's end closed
                        return
        finally:
            self._closing.set()
            with contextlib.suppress(OSError):
                os.close(self.master)

    def _board_to_master(self) -> None:
        """The firmware's bytes to the companion; the firmware's end closing closes the line."""
        try:
            while True:
                try:
                    data = self._sock.recv(CHUNK)
                except OSError:
                    return
                if not data:
                    return
                self._wait_stall()
                if not self._write_master(data):
                    return
        finally:
            self._closing.set()

    def stall(self, seconds: float) -> None:
        """Hold every byte, both ways, for ``seconds`` of wall time from now."""
        if not (seconds >= 0 and seconds < 60):
            raise ValueError(f"a stall lasts 0 to 60 s, not {seconds!r}")
        self._stalled_until = time.monotonic() + seconds

    def _wait_stall(self) -> None:
        while not self._closing.is_set():
            left = self._stalled_until - time.monotonic()
            if left <= 0:
                return
            self._closing.wait(min(left, LOOK_S))

    def _write_master(self, data: bytes) -> bool:
        """Write all of ``data`` to the master side, waiting while the companion's side is full
        (the firmware's own writes then find the socket full, and drop, as a UART's full FIFO
        does); False once the line is closing."""
        while data:
            try:
                n = os.write(self.master, data)
            except BlockingIOError:
                n = 0
            except OSError:  # the master side closed under us: the line is closing
                return False
            data = data[n:]
            if data:
                if self._closing.is_set():
                    return False
                time.sleep(FULL_WAIT_S)
        return True

    def close(self) -> None:
        """End the relay and close the master side (and the board's end, if never taken)."""
        self._closing.set()
        with contextlib.suppress(OSError):
            self._sock.shutdown(socket.SHUT_RDWR)
        self._to_board.join(2.0)
        self._to_master.join(2.0)
        self._sock.close()
        if self._board_fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._board_fd)
            self._board_fd = None
