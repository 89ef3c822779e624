"""Byte bridges between a TCP socket and a UNIX socket, one thread per connection pair.

ArduCopter runs in its own network namespace (:mod:`slopelander_sitl.netns`); a UNIX socket is a file, so it
crosses from that namespace to this one. Inside, each connection to ``<folder>/serialN.sock`` is
joined to ArduCopter's TCP port; outside, each connection to a loopback TCP port is joined to that
socket. A bridge forwards every byte in order and closes both sides when either closes, so a
client that disconnects is seen by ArduCopter as the disconnect it is.
"""

from __future__ import annotations

import contextlib
import selectors
import socket
import threading
import time
from collections.abc import Callable

CHUNK = 65536


#: a reader of the bytes going one way through a bridge: called after they were forwarded; its
#: ``close()``, if it has one, is called when the connection ends
Tap = Callable[[bytes], None]


def splice(a: socket.socket, b: socket.socket, stop: threading.Event, tap_a: Tap | None = None) -> None:
    """Forward bytes both ways until either side closes or ``stop`` is set; then close both.
    ``tap_a`` reads, after forwarding, each chunk that came from ``a``."""
    sel = selectors.DefaultSelector()
    sel.register(a, selectors.EVENT_READ, b)
    sel.register(b, selectors.EVENT_READ, a)
    try:
        while not stop.is_set():
            for key, _ in sel.select(timeout=0.2):
                try:
                    data = key.fileobj.recv(CHUNK)
                except OSError:
                    data = b""
                if not data:
                    return
                try:
                    key.data.sendall(data)
                except OSError:
                    return
                if tap_a is not None and key.fileobj is a:
                    tap_a(data)
    finally:
        sel.close()
        closing = getattr(tap_a, "close", None)
        if closing is not None:
            closing()
        for s in (a, b):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()


def nodelay(s: socket.socket) -> socket.socket:
    if s.family in (socket.AF_INET, socket.AF_INET6):
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def connect_retrying(make: Callable[[], socket.socket], timeout_s: float) -> socket.socket:
    """The first connection ``make`` gets within ``timeout_s``; the last OSError after it."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return make()
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


class Bridge:
    """Accept on ``listener``; join each accepted connection to a new one from ``connect``.
    ``tap``: makes, for each connection, a reader of the bytes its client sends."""

    def __init__(
        self,
        listener: socket.socket,
        connect: Callable[[], socket.socket],
        name: str,
        tap: Callable[[], Tap] | None = None,
    ) -> None:
        self.listener, self.connect, self.name, self.tap = listener, connect, name, tap
        self.stop_event = threading.Event()
        self.errors: list[str] = []
        self.thread = threading.Thread(target=self._serve, name=f"bridge-{name}", daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        self.listener.settimeout(0.2)
        while not self.stop_event.is_set():
            try:
                client, _ = self.listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                other = nodelay(self.connect())
            except OSError as exc:
                self.errors.append(f"{self.name}: {exc}")
                client.close()
                continue
            client.settimeout(None)
            other.settimeout(None)
            tap = self.tap() if self.tap is not None else None
            threading.Thread(
                target=splice, args=(nodelay(client), other, self.stop_event, tap), daemon=True
            ).start()

    def close(self) -> None:
        self.stop_event.set()
        self.listener.close()
        self.thread.join(2.0)


def tcp_to_unix(path: str, name: str, host: str = "127.0.0.1", port: int = 0) -> tuple[Bridge, int]:
    """Listen on ``host:port`` (0: a free port) and join each client to the UNIX socket ``path``.
    Returns the bridge and the port."""
    lst = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    lst.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    lst.bind((host, port))
    lst.listen(4)

    def connect() -> socket.socket:
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.connect(path)
        return s

    return Bridge(lst, connect, name), lst.getsockname()[1]


def unix_to_tcp(
    path: str,
    port: int,
    name: str,
    connect_timeout_s: float = 30.0,
    tap: Callable[[], Tap] | None = None,
) -> Bridge:
    """Listen on the UNIX socket ``path`` and join each client to TCP ``127.0.0.1:port``
    (``tap``: see :class:`Bridge`)."""
    lst = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    lst.bind(path)
    lst.listen(4)

    def connect() -> socket.socket:
        return connect_retrying(
            lambda: socket.create_connection(("127.0.0.1", port), timeout=2.0), connect_timeout_s
        )

    return Bridge(lst, connect, name, tap)
