"""Reading the autopilot's bytes: every waiting message, without blocking.

Two readers. :func:`read_all` is pymavlink's own (``recv_match``: every message decoded, its
``messages`` store and packet-loss counts kept). :func:`read_filtered` reads raw bytes, drops the
frames of messages nobody reads before decoding (:mod:`.frames`: decoding in Python is most of the
companion's CPU at the full IMU rate) and decodes the rest with the connection's own parser; the
tlog, when one is set up, gets the decoded messages as pymavlink would write them.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable

from slopelander.controller.link.frames import FrameFilter

#: the largest read from the link per call (a UDP read returns one datagram whatever this is)
RECV_BYTES = 4096


def read_all(conn, handle: Callable[[object], None], monotonic: Callable[[], float]) -> tuple[int, float]:
    """Hand every waiting message to ``handle``; the count, and the local time of the read that
    found the link drained."""
    n = 0
    while True:
        looked = monotonic()
        msg = conn.recv_match(blocking=False)
        if msg is None:
            return n, looked
        n += 1
        handle(msg)


def read_filtered(
    conn, keep: FrameFilter, handle: Callable[[object], None], monotonic: Callable[[], float]
) -> tuple[int, float]:
    """As :func:`read_all`, decoding only the frames ``keep`` lets through."""
    n = 0
    while True:
        looked = monotonic()
        data = conn.recv(RECV_BYTES)
        if data:
            if conn.logfile_raw:
                conn.logfile_raw.write(data)
            if conn.first_byte:
                conn.auto_mavlink_version(data)
            data = keep.feed(data)
        # whole frames only reach the parser, but an empty read still drains its buffer
        msgs = conn.mav.parse_buffer(data or b"") or ()
        for msg in msgs:
            if conn.logfile and msg.get_type() != "BAD_DATA":
                usec = int(time.time() * 1.0e6) & ~3
                conn.logfile.write(struct.pack(">Q", usec) + msg.get_msgbuf())
            n += 1
            handle(msg)
        if not data and not msgs:
            return n, looked
