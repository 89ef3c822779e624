"""The relay itself: real sockets, whole MAVLink frames, a thread per direction.

Frames are found with pymavlink's own parser (``MAVLink.parse_buffer`` and the bytes of each
message as they arrived), so a fault always hits a whole frame, as on a radio link, and the
byte stream between faults stays valid MAVLink.
"""

from __future__ import annotations

import heapq
import itertools
import json
import os
import random
import socket
import threading
import time
from collections.abc import Callable

os.environ.setdefault("MAVLINK20", "1")
import contextlib

from pymavlink import mavutil

from slopelander_sitl.linkfault.faults import FaultConfigError, LinkFaults, decide


def _no_delay(sock: socket.socket) -> None:
    """Send each frame at once. With Nagle's algorithm a small frame waits for the peer's delayed
    ACK (up to 40 ms on Linux): a lock-stepped vehicle behind the relay then ran at about real time
    whatever its ``--speed`` (pymavlink's own TCP links set this too)."""
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


def parse_address(url: str) -> tuple[str, str, int]:
    """``tcp:HOST:PORT`` or ``udp:HOST:PORT`` -> (kind, host, port), with a clear error."""
    parts = url.split(":")
    if len(parts) != 3 or parts[0] not in ("tcp", "udp") or not parts[2].isdigit():
        raise FaultConfigError(f"{url!r}: expected tcp:HOST:PORT or udp:HOST:PORT")
    return parts[0], parts[1], int(parts[2])


class _Direction:
    """One way through the relay: frames in, faults drawn, frames out at their due time."""

    def __init__(self, name: str, relay: Relay, seed: int) -> None:
        self.name = name
        self.relay = relay
        self.rng = random.Random(f"{seed}:{name}")
        self.parser = mavutil.mavlink.MAVLink(None)
        self.parser.robust_parsing = True
        self.heap: list[tuple[float, int, bytes]] = []
        self.order = itertools.count()
        self.held: bytes | None = None
        self.cv = threading.Condition()
        self.send: Callable[[bytes], None] | None = None
        self.counts = dict(
            frames=0, sent=0, dropped=0, cut=0, duplicated=0, reordered=0, corrupted=0, blocked=0
        )

    def reset(self, send: Callable[[bytes], None] | None) -> None:
        with self.cv:
            self.parser = mavutil.mavlink.MAVLink(None)
            self.parser.robust_parsing = True
            self.heap.clear()
            self.held = None
            self.send = send

    def feed(self, data: bytes) -> None:
        msgs = self.parser.parse_buffer(data) or []
        for m in msgs:
            if self is self.relay.down:
                self.relay.observe(m)
            elif (
                getattr(m, "command", None) in self.relay.blocked_commands and m.get_type() == "COMMAND_LONG"
            ):
                with self.cv:
                    self.counts["blocked"] += 1
                continue
            raw = bytes(m.get_msgbuf()) if hasattr(m, "get_msgbuf") else bytes(getattr(m, "data", b""))
            if raw:
                self.frame(raw)

    def inject(self, raw: bytes) -> None:
        """Send ``raw`` now, past the faults (the relay's own frames)."""
        with self.cv:
            heapq.heappush(self.heap, (time.monotonic(), next(self.order), raw))
            self.cv.notify()

    def frame(self, raw: bytes) -> None:
        now = time.monotonic()
        cut = self.relay.is_cut(now)
        with self.cv:
            self.counts["frames"] += 1
            if cut:
                self.counts["cut"] += 1
                return
            d = decide(raw, self.relay.faults, self.rng)
            if d.copies == 0:
                self.counts["dropped"] += 1
                return
            if d.data != raw:
                self.counts["corrupted"] += 1
            if d.copies > 1:
                self.counts["duplicated"] += 1
            if d.hold and self.held is None:
                self.held = d.data
                self.counts["reordered"] += 1
                return
            due = now + d.delay_s
            for _ in range(d.copies):
                heapq.heappush(self.heap, (due, next(self.order), d.data))
            if self.held is not None:
                heapq.heappush(self.heap, (due, next(self.order), self.held))
                self.held = None
            self.cv.notify()

    def run_sender(self, stop: threading.Event) -> None:
        while not stop.is_set():
            with self.cv:
                if not self.heap:
                    self.cv.wait(0.05)
                    continue
                due = self.heap[0][0]
                now = time.monotonic()
                if due > now:
                    self.cv.wait(min(0.05, due - now))
                    continue
                _, _, data = heapq.heappop(self.heap)
                send = self.send
            if send is None:
                continue
            try:
                send(data)
                self.counts["sent"] += 1
            except OSError:
                pass  # the peer went away; the reader notices and resets


#: fields that carry the vehicle's time, in microseconds or milliseconds
_TIME_FIELDS = (("time_usec", 1e-6), ("time_boot_ms", 1e-3))
ECHO_PERIOD_S = 0.005  # wall seconds between the relay's own lock-step echoes during a cut


class Relay:
    """A fault-injecting MAVLink relay from ``listen`` (where the companion connects) to ``to``
    (the vehicle), TCP or UDP on both sides, with an optional UDP control port.

    ``lockstep``: the vehicle behind the relay is a lock-stepped simulator (``slopelander_sitl.vehicle
    --lockstep``), which waits for the companion's TIMESYNC echo. A cut would freeze it, then (after
    its give-up second) let it run free as fast as it can, so a cut's length in vehicle time would
    depend on the machine's load. With ``lockstep`` the relay stands in for the companion during a
    cut: it echoes the vehicle's time paced to the wall clock, so the vehicle runs in real time (or
    slower, never faster) while the link is gone, as a real one would, and a cut of N seconds lasts
    N seconds of vehicle time (and at least N of wall time: the companion sees all of it)."""

    def __init__(
        self,
        listen: str,
        to: str,
        faults: LinkFaults | None = None,
        seed: int = 0,
        control_port: int | None = None,
        lockstep: bool = False,
    ) -> None:
        self.listen_kind, lh, lp = parse_address(listen)
        self.to_kind, th, tp = parse_address(to)
        self.listen_addr, self.to_addr = (lh, lp), (th, tp)
        self.faults = faults or LinkFaults()
        #: COMMAND_LONG ids the relay never passes to the vehicle (:meth:`block_commands`)
        self.blocked_commands: frozenset[int] = frozenset()
        self._cut_until = 0.0
        self.lockstep = lockstep
        self.vehicle_t: float | None = None  # newest vehicle time seen going down (s)
        self._cut_from: tuple[float, float] | None = None  # (vehicle s, wall s) where a cut began
        self._cut_vehicle_until = 0.0
        self._echo = mavutil.mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self._lock = threading.Lock()
        self.up = _Direction("up", self, seed)  # companion -> vehicle
        self.down = _Direction("down", self, seed)  # vehicle -> companion
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._socks: list[socket.socket] = []
        self.control_port_wanted = control_port
        self.control_port: int | None = None
        self.port: int = 0

    # -- faults ------------------------------------------------------------------------------
    def is_cut(self, now: float) -> bool:
        with self._lock:
            if self._cut_from is not None:  # lock-step: the cut runs on vehicle time
                if self.vehicle_t is not None and self.vehicle_t >= self._cut_vehicle_until:
                    self._cut_from = None
                    return False
                return True
            return now < self._cut_until

    def cut(self, seconds: float | None) -> None:
        """Lose every frame both ways for ``seconds`` (None: for good, until :meth:`restore`);
        vehicle seconds with ``lockstep`` (once the relay has seen the vehicle's time), else wall."""
        if seconds is not None and (not isinstance(seconds, (int, float)) or not 0 <= seconds <= 3600):
            raise FaultConfigError(f"cut seconds = {seconds!r}: must lie within 0..3600 (or none: for good)")
        with self._lock:
            if self.lockstep and self.vehicle_t is not None:
                self._cut_from = (self.vehicle_t, time.monotonic())
                self._cut_vehicle_until = float("inf") if seconds is None else self.vehicle_t + seconds
            else:
                self._cut_until = float("inf") if seconds is None else time.monotonic() + seconds

    def restore(self) -> None:
        with self._lock:
            self._cut_until = 0.0
            self._cut_from = None

    def observe(self, msg) -> None:
        """Follow the vehicle's time in the frames going down (for ``lockstep``)."""
        if not self.lockstep:
            return
        for name, scale in _TIME_FIELDS:
            stamp = getattr(msg, name, None)
            if isinstance(stamp, int) and stamp > 0:
                t = stamp * scale
                with self._lock:
                    if self.vehicle_t is None or t > self.vehicle_t:
                        self.vehicle_t = t
                return

    def _pace(self, stop: threading.Event) -> None:
        """During a lock-step cut, echo the vehicle's time no faster than the wall clock."""
        while not stop.wait(ECHO_PERIOD_S):
            with self._lock:
                start, seen = self._cut_from, self.vehicle_t
            if start is None or seen is None:
                continue
            t_cut, wall_cut = start
            echo = min(seen, t_cut + (time.monotonic() - wall_cut))
            msg = mavutil.mavlink.MAVLink_timesync_message(max(1, time.monotonic_ns()), int(echo * 1e9))
            self.up.inject(bytes(msg.pack(self._echo)))

    def set_faults(self, changes: dict) -> None:
        self.faults = self.faults.updated(changes)

    def block_commands(self, *commands: int) -> None:
        """Lose every COMMAND_LONG of these ids from the companion (none: pass them all again):
        one command lost for good, e.g. the abort's LOITER, while everything else goes through."""
        self.blocked_commands = frozenset(commands)

    def stats(self) -> dict:
        return {
            "up": dict(self.up.counts),
            "down": dict(self.down.counts),
            "cut": self.is_cut(time.monotonic()),
        }

    # -- running -----------------------------------------------------------------------------
    def start(self) -> Relay:
        for d in (self.up, self.down):
            self._spawn(d.run_sender, self._stop)
        if self.lockstep:
            self._spawn(self._pace, self._stop)
        if self.listen_kind == "tcp":
            srv = socket.create_server(self.listen_addr)
            srv.settimeout(0.2)
            self._socks.append(srv)
            self.port = srv.getsockname()[1]
            self._spawn(self._tcp_accept, srv)
        else:
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.bind(self.listen_addr)
            s.settimeout(0.2)
            self._socks.append(s)
            self.port = s.getsockname()[1]
            self._spawn(self._udp_serve, s)
        if self.control_port_wanted is not None:
            c = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            c.bind(("127.0.0.1", self.control_port_wanted))
            c.settimeout(0.2)
            self._socks.append(c)
            self.control_port = c.getsockname()[1]
            self._spawn(self._control, c)
        return self

    def stop(self) -> None:
        self._stop.set()
        for s in self._socks:
            with contextlib.suppress(OSError):
                s.close()
        for t in self._threads:
            t.join(2.0)

    def __enter__(self) -> Relay:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _spawn(self, fn: Callable, *args: object) -> None:
        t = threading.Thread(target=fn, args=args, daemon=True, name=f"linkfault-{fn.__name__}")
        t.start()
        self._threads.append(t)

    def _upstream(self) -> socket.socket:
        if self.to_kind == "tcp":
            u = socket.create_connection(self.to_addr, timeout=5.0)
            _no_delay(u)
        else:
            u = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            u.connect(self.to_addr)
        u.settimeout(0.2)
        self._socks.append(u)
        return u

    def _pump(self, sock: socket.socket, direction: _Direction, alive: threading.Event) -> None:
        """Read from one side until it closes; feed the frames to one direction."""
        while not self._stop.is_set() and alive.is_set():
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                break
            if not data and sock.type == socket.SOCK_STREAM:
                break
            direction.feed(data)
        alive.clear()

    def _tcp_accept(self, srv: socket.socket) -> None:
        while not self._stop.is_set():
            try:
                client, _ = srv.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            client.settimeout(0.2)
            _no_delay(client)
            self._socks.append(client)  # closed by stop() too
            try:
                up = self._upstream()
            except OSError:
                client.close()
                continue
            alive = threading.Event()
            alive.set()
            self.up.reset(up.sendall)
            self.down.reset(client.sendall)
            a = threading.Thread(target=self._pump, args=(client, self.up, alive), daemon=True)
            b = threading.Thread(target=self._pump, args=(up, self.down, alive), daemon=True)
            a.start()
            b.start()
            while alive.is_set() and not self._stop.is_set():
                time.sleep(0.1)
            for s in (client, up):
                with contextlib.suppress(OSError):
                    s.close()
            a.join(1.0)
            b.join(1.0)

    def _udp_serve(self, s: socket.socket) -> None:
        up = self._upstream()
        client: list[tuple[str, int] | None] = [None]

        def send_down(data: bytes) -> None:
            if client[0] is not None:
                s.sendto(data, client[0])

        self.up.reset(up.send)
        self.down.reset(send_down)
        alive = threading.Event()
        alive.set()
        threading.Thread(target=self._pump, args=(up, self.down, alive), daemon=True).start()
        while not self._stop.is_set():
            try:
                data, addr = s.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            client[0] = addr
            self.up.feed(data)

    def _control(self, c: socket.socket) -> None:
        while not self._stop.is_set():
            try:
                data, addr = c.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                req = json.loads(data)
                cmd = req.get("cmd")
                if cmd == "cut":
                    self.cut(req.get("seconds"))
                elif cmd == "restore":
                    self.restore()
                elif cmd == "set":
                    self.set_faults(req.get("faults", {}))
                elif cmd != "stats":
                    raise FaultConfigError(f"unknown command {cmd!r}: cut, restore, set or stats")
                reply = {"ok": True, **self.stats()}
            except (ValueError, AttributeError, TypeError) as e:
                reply = {"ok": False, "error": str(e)}
            c.sendto(json.dumps(reply).encode(), addr)


class RelayControl:
    """Steer a relay process through its control port."""

    def __init__(self, port: int, host: str = "127.0.0.1", timeout: float = 2.0) -> None:
        self.addr = (host, port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(timeout)

    def _call(self, **req: object) -> dict:
        self.sock.sendto(json.dumps(req).encode(), self.addr)
        reply = json.loads(self.sock.recv(65536))
        if not reply.get("ok"):
            raise FaultConfigError(reply.get("error", "the relay refused the command"))
        return reply

    def cut(self, seconds: float | None) -> dict:
        return self._call(cmd="cut", seconds=seconds)

    def restore(self) -> dict:
        return self._call(cmd="restore")

    def set(self, **faults: float) -> dict:
        return self._call(cmd="set", faults=faults)

    def stats(self) -> dict:
        return self._call(cmd="stats")

    def close(self) -> None:
        self.sock.close()
