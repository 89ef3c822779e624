"""Companion-side driver of the leg board (pyserial).

Two ways to use it. A landing state machine starts an operation and polls it each tick::

    op = board.start_presets(uphill_nm=1.7, downhill_nm=2.3, timeout=20.0)
    ...                      # every tick:
    board.poll()             # reads the port; raises on a lost or garbled link
    results = op.check()     # None while running; per-leg results; raises a typed error

A script calls the blocking forms, which do the same with a deadline::

    with LegBoard.open("/dev/ttyACM0", 115200) as board:
        board.set_torques(uphill=1.7, downhill=2.3, timeout=20.0)

Timeouts are wall-clock seconds. Nothing here waits without a deadline.
"""

from __future__ import annotations

import collections
import contextlib
import select
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import serial

from slopelander.legs import codec, messages
from slopelander.legs.calibration import Calibration, load_calibration
from slopelander.legs.errors import (
    BoardDisconnected,
    CommandRejected,
    LegBoardError,
    LegFault,
    LegNotConverged,
    LegTimeout,
    ProtocolError,
)
from slopelander.legs.messages import (
    FAULT_TEXT,
    MAX_ANGLE_CDEG,
    N_LEGS,
    NAK_TEXT,
    Capability,
    FaultCode,
    LegState,
    MsgType,
    mask_of,
)

MAX_ANGLE_DEG = MAX_ANGLE_CDEG / 100.0
STEADY_STATES = (LegState.LOOSE, LegState.HOLDING, LegState.STOPPED)
SETTLE_SAMPLES = 3


@dataclass(frozen=True)
class PairMap:
    """Which legs form the uphill and the downhill pair; set by the caller per landing."""

    uphill: tuple[int, ...] = (0, 1)
    downhill: tuple[int, ...] = (2, 3)

    def __post_init__(self) -> None:
        legs = self.uphill + self.downhill
        if len(set(legs)) != len(legs) or not all(0 <= i < N_LEGS for i in legs):
            raise ValueError(f"pairs must be distinct legs 0..{N_LEGS - 1}: {self}")

    def legs(self, pair: str) -> tuple[int, ...]:
        if pair not in ("uphill", "downhill"):
            raise ValueError(f"pair must be 'uphill' or 'downhill', not {pair!r}")
        return getattr(self, pair)


@dataclass(frozen=True)
class BoardInfo:
    """What the board said in its HELLO_REPLY."""

    version: int
    legs: int
    capabilities: int
    max_payload: int
    board_time_s: float

    @property
    def angle_stop(self) -> bool:
        return bool(self.capabilities & Capability.ANGLE_STOP)

    @property
    def simulated(self) -> bool:
        return bool(self.capabilities & Capability.SIMULATED)


@dataclass(frozen=True)
class LegStatus:
    """One leg as last reported; ``torque_nm`` is estimated from the current.

    The estimate exists only while the motor regulates current (TIGHTENING, HOLDING);
    it is 0 when LOOSE and None otherwise (a stopped motor's current says nothing).
    """

    leg: int
    state: LegState
    fault: FaultCode
    current_ma: int
    target_ma: int
    angle_deg: float
    torque_nm: float | None


@dataclass(frozen=True)
class BoardStatus:
    """The latest STATUS, in engineering units, with the wall time it arrived."""

    board_time_s: float
    legs: tuple[LegStatus, ...]
    received_at: float
    last_cmd_seq: int

    @property
    def ready(self) -> bool:
        return all(s.state in STEADY_STATES for s in self.legs)

    @property
    def faults(self) -> tuple[LegStatus, ...]:
        return tuple(s for s in self.legs if s.state is LegState.FAULT)


@dataclass(frozen=True)
class LegResult:
    """Outcome of an operation for one leg.

    ``target``/``achieved`` are N·m for friction, degrees for angles and loosening.
    ``board_seconds`` is how long the leg took in the board's clock.
    """

    leg: int
    converged: bool
    target: float | None
    achieved: float
    current_ma: float
    target_ma: int | None
    angle_deg: float
    board_seconds: float | None


@dataclass
class Operation:
    """A command in flight and the per-leg convergence of its effect."""

    kind: str
    legs: tuple[int, ...]
    targets: dict[int, float]
    target_ma: dict[int, int]
    deadline: float
    tolerance: float
    start_board_s: float
    acked: bool = False
    error: LegBoardError | None = None
    results: dict[int, LegResult] = field(default_factory=dict)
    _samples: dict[int, collections.deque] = field(default_factory=dict)
    _settled_at: dict[int, float] = field(default_factory=dict)

    def acknowledge(self, status: BoardStatus | None) -> None:
        """The board took the command: board time counts from its latest status."""
        self.acked = True
        if status is not None:
            self.start_board_s = status.board_time_s

    @property
    def done(self) -> bool:
        return self.error is not None or len(self.results) == len(self.legs)

    def check(self) -> dict[int, LegResult] | None:
        """Per-leg results once every leg converged; None while running; raises on failure."""
        if self.error is not None:
            raise self.error
        if len(self.results) == len(self.legs):
            return dict(sorted(self.results.items()))
        return None

    def fail(self, error: LegBoardError) -> None:
        if not self.done:
            self.error = error

    def update(self, status: BoardStatus, calibration: Calibration) -> None:
        if self.done or not self.acked:
            return
        for leg in self.legs:
            if leg in self.results:
                continue
            s = status.legs[leg]
            if s.state is LegState.FAULT:
                self.fail(LegFault(leg, int(s.fault), FAULT_TEXT[s.fault]))
                return
            samples = self._samples.setdefault(leg, collections.deque(maxlen=SETTLE_SAMPLES))
            if self._counts(s):
                if not samples:
                    self._settled_at[leg] = status.board_time_s
                samples.append((s.current_ma, s.angle_deg))
            else:
                samples.clear()
            if len(samples) == SETTLE_SAMPLES:
                result = self._result(leg, status, calibration, final=False)
                if result.converged:
                    self.results[leg] = result

    def expire(self, status: BoardStatus | None, calibration: Calibration) -> None:
        """Past the deadline: fail with the first leg that has not converged."""
        if self.done:
            return
        if not self.acked:
            self.fail(LegTimeout(f"{self.kind}: the board never acknowledged the command"))
            return
        partial = dict(self.results)
        for leg in self.legs:
            if leg not in partial and status is not None:
                partial[leg] = self._result(leg, status, calibration, final=True)
        for leg in self.legs:
            if leg not in self.results:
                r = partial.get(leg)
                unit = "N·m" if self.kind == "friction" else "°"
                state = status.legs[leg].state.name if status else "unknown"
                self.fail(
                    LegNotConverged(
                        leg,
                        self.targets.get(leg, float("nan")),
                        r.achieved if r else float("nan"),
                        unit=unit,
                        detail=f"state {state}, current {r.current_ma:.0f} mA of "
                        f"{self.target_ma.get(leg, 0)} mA"
                        if r
                        else "no status",
                        results=partial,
                    )
                )
                return

    def _counts(self, s: LegStatus) -> bool:
        """Whether this status is one of the settled samples the leg needs."""
        if self.kind == "friction":
            if self.target_ma[s.leg] == 0:
                return s.state is LegState.LOOSE
            return s.state is LegState.HOLDING and s.target_ma == self.target_ma[s.leg]
        if self.kind == "stop":
            return s.state is LegState.STOPPED
        return s.state is LegState.LOOSE  # loosen, angle

    def _result(self, leg: int, status: BoardStatus, cal: Calibration, final: bool) -> LegResult:
        s = status.legs[leg]
        samples = list(self._samples.get(leg, ()))
        current = sum(c for c, _ in samples) / len(samples) if samples and not final else float(s.current_ma)
        angles = [a for _, a in samples] or [s.angle_deg]
        angle = angles[-1]
        target = self.targets.get(leg)
        if self.kind == "friction":
            achieved = cal.torque(leg, current) if self.target_ma[leg] else 0.0
            ok = target is not None and abs(achieved - target) <= self.tolerance
        elif self.kind == "angle":
            achieved = angle
            ok = target is not None and abs(angle - target) <= self.tolerance
        else:  # loosen, stop: settled when the angle stops moving
            achieved = angle
            ok = max(angles) - min(angles) <= self.tolerance
        return LegResult(
            leg,
            ok and not final,
            target,
            achieved,
            current,
            self.target_ma.get(leg),
            angle,
            self._settled_at.get(leg, status.board_time_s) - self.start_board_s,
        )


@dataclass
class _Pending:
    data: bytes
    msg_type: int
    op: Operation | None
    sent_at: float
    tries: int = 1


class LegBoard:
    """A handshaken connection to one leg board."""

    def __init__(
        self,
        port: str,
        baud: int = 115200,
        *,
        calibration: Calibration | str | Path | None = None,
        pairs: PairMap | None = None,
        status_period_ms: int = 100,
        silence_timeout: float = 1.0,
        ack_timeout: float = 0.25,
        ack_retries: int = 4,
        serial_factory: Callable[..., serial.Serial] = serial.Serial,
    ) -> None:
        self.port = port
        self.baud = baud
        self.calibration = (
            calibration if isinstance(calibration, Calibration) else load_calibration(calibration)
        )
        self.pairs = pairs or PairMap()
        self.status_period_ms = status_period_ms
        self.silence_timeout = silence_timeout
        self.ack_timeout = ack_timeout
        self.ack_retries = ack_retries
        self.info: BoardInfo | None = None
        self.status: BoardStatus | None = None
        self.decoder = codec.Decoder()
        self._serial_factory = serial_factory
        self._ser: serial.Serial | None = None
        self._seq = 0
        self._pending: dict[int, _Pending] = {}
        self._ops: list[Operation] = []
        self._last_good = 0.0
        self._rejects_at_good = 0

    # ---- connection -------------------------------------------------------------------
    @classmethod
    def open(cls, port: str, baud: int = 115200, *, timeout: float = 2.0, **kw) -> LegBoard:
        """Open the port and handshake; raises a :class:`LegBoardError` on failure."""
        board = cls(port, baud, **kw)
        try:
            board.connect(timeout)
        except BaseException:
            board.close()
            raise
        return board

    def connect(self, timeout: float = 2.0) -> BoardInfo:
        try:
            self._ser = self._serial_factory(
                self.port, self.baud, timeout=0, write_timeout=0.5, exclusive=True
            )
            self._ser.reset_input_buffer()
        except (serial.SerialException, OSError, ValueError) as exc:
            raise BoardDisconnected(f"cannot open leg board port {self.port}: {exc}") from None
        deadline = time.monotonic() + timeout
        hello = messages.Hello(messages.PROTOCOL_VERSION, self.status_period_ms)
        self._write(b"\x00")
        next_try = 0.0
        while True:
            now = time.monotonic()
            if now >= next_try:
                seq = self._send(hello)
                next_try = now + self.ack_timeout
            for frame in self._read():
                msg = frame.message
                if isinstance(msg, messages.HelloReply):
                    if msg.version != messages.PROTOCOL_VERSION:
                        raise ProtocolError(
                            f"leg board on {self.port} speaks protocol version {msg.version}, "
                            f"this driver {messages.PROTOCOL_VERSION}"
                        )
                    self.info = BoardInfo(
                        msg.version,
                        msg.legs,
                        msg.capabilities,
                        msg.max_payload,
                        msg.board_time_ms / 1000.0,
                    )
                    self._last_good = time.monotonic()
                    self._rejects_at_good = self.decoder.rejects.total()
                    return self.info
                if isinstance(msg, messages.Nak) and msg.cmd_seq == seq:
                    raise ProtocolError(
                        f"leg board on {self.port} refused HELLO: {NAK_TEXT.get(msg.code, msg.code)}"
                    )
            if time.monotonic() >= deadline:
                raise self._silence_error(f"no HELLO_REPLY within {timeout:g} s")
            self._wait_readable(min(next_try, deadline) - time.monotonic())

    def close(self) -> None:
        if self._ser is not None:
            with contextlib.suppress(serial.SerialException, OSError):
                self._ser.close()
            self._ser = None

    def __enter__(self) -> LegBoard:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- the non-blocking path --------------------------------------------------------
    def poll(self) -> BoardStatus | None:
        """Read what has arrived, resend unacknowledged commands, update operations.

        Returns the latest status. Raises :class:`BoardDisconnected`, :class:`LegTimeout`
        (nothing for ``silence_timeout``) or :class:`ProtocolError` (only garbage); the
        running operations fail with the same error.
        """
        try:
            self._read()
            now = time.monotonic()
            self._resend(now)
            if now - self._last_good > self.silence_timeout:
                raise self._silence_error(f"nothing for {self.silence_timeout:g} s")
        except LegBoardError as exc:
            for op in self._ops:
                op.fail(exc)
            self._ops.clear()
            raise
        for op in self._ops:
            if now > op.deadline:
                op.expire(self.status, self.calibration)
        self._ops = [op for op in self._ops if not op.done]
        return self.status

    def start_torques(
        self, torques: Mapping[int, float], *, timeout: float = 20.0, tolerance_nm: float = 0.1
    ) -> Operation:
        """Start setting friction torques (N·m per real joint) on the given legs.

        Torques are checked against each leg's calibration before anything is sent; a
        torque of 0 loosens the leg.
        """
        legs = self._legs(torques)
        target_ma = {leg: self.calibration.current_for(leg, torques[leg]) for leg in legs}
        for leg in legs:
            if torques[leg] == 0:
                target_ma[leg] = 0
        currents = tuple(target_ma.get(i, 0) for i in range(N_LEGS))
        msg = messages.SetFriction(mask_of(legs), currents)
        return self._start("friction", msg, legs, dict(torques), target_ma, timeout, tolerance_nm)

    def start_presets(
        self,
        uphill_nm: float | None = None,
        downhill_nm: float | None = None,
        *,
        timeout: float = 20.0,
        tolerance_nm: float = 0.1,
    ) -> Operation:
        """Start setting the uphill and/or downhill pair's torque through :attr:`pairs`."""
        torques: dict[int, float] = {}
        for pair, value in (("uphill", uphill_nm), ("downhill", downhill_nm)):
            if value is not None:
                torques.update(dict.fromkeys(self.pairs.legs(pair), value))
        if not torques:
            raise ValueError("give an uphill or a downhill torque")
        return self.start_torques(torques, timeout=timeout, tolerance_nm=tolerance_nm)

    def start_loosen(self, legs: Iterable[int] | None = None, *, timeout: float = 20.0) -> Operation:
        """Start loosening legs (all by default) so their springs reset them."""
        legs = self._legs(range(N_LEGS) if legs is None else legs)
        return self._start("loosen", messages.Loosen(mask_of(legs)), legs, {}, {}, timeout, 0.1)

    def start_angles(
        self, angles_deg: Mapping[int, float], *, timeout: float = 20.0, tolerance_deg: float = 0.5
    ) -> Operation:
        """Start moving legs' rest angles (degrees, 0..37.5); needs the ANGLE_STOP capability.

        The legs end loose at their new angle; set friction afterwards to clamp them.
        """
        legs = self._legs(angles_deg)
        for leg in legs:
            if not 0.0 <= angles_deg[leg] <= MAX_ANGLE_DEG:
                raise ValueError(f"leg {leg}: angle {angles_deg[leg]}° outside 0–37.5°")
        if self.info is not None and not self.info.angle_stop:
            raise CommandRejected(
                "SET_ANGLE", 3, "this board cannot set leg angles; set them by hand before flight"
            )
        cdeg = tuple(round(angles_deg.get(i, 0.0) * 100) for i in range(N_LEGS))
        msg = messages.SetAngle(mask_of(legs), cdeg)
        return self._start("angle", msg, legs, dict(angles_deg), {}, timeout, tolerance_deg)

    def start_stop(self, legs: Iterable[int] | None = None, *, timeout: float = 2.0) -> Operation:
        """Stop motors where they are (the screw holds the clamping)."""
        legs = self._legs(range(N_LEGS) if legs is None else legs)
        return self._start("stop", messages.Stop(mask_of(legs)), legs, {}, {}, timeout, 0.1)

    # ---- blocking conveniences --------------------------------------------------------
    def wait(self, op: Operation) -> dict[int, LegResult]:
        """Poll until ``op`` finishes (bounded by its deadline); results or a typed error."""
        while True:
            self.poll()
            results = op.check()
            if results is not None:
                return results
            self._wait_readable(0.02)

    def set_torques(
        self,
        uphill: float | None = None,
        downhill: float | None = None,
        *,
        legs: Mapping[int, float] | None = None,
        timeout: float = 20.0,
        tolerance_nm: float = 0.1,
    ) -> dict[int, LegResult]:
        """Set pair and/or per-leg torques (N·m) and wait until each leg converged."""
        torques: dict[int, float] = {}
        for pair, value in (("uphill", uphill), ("downhill", downhill)):
            if value is not None:
                torques.update(dict.fromkeys(self.pairs.legs(pair), value))
        torques.update(legs or {})
        if not torques:
            raise ValueError("give an uphill, a downhill or a per-leg torque")
        return self.wait(self.start_torques(torques, timeout=timeout, tolerance_nm=tolerance_nm))

    def set_leg_angles(
        self, angles_deg: Mapping[int, float], *, timeout: float = 20.0
    ) -> dict[int, LegResult]:
        return self.wait(self.start_angles(angles_deg, timeout=timeout))

    def loosen_all(self, *, timeout: float = 20.0) -> dict[int, LegResult]:
        """Loosen every leg and wait until each is loose and its angle has settled."""
        return self.wait(self.start_loosen(timeout=timeout))

    def stop(self, legs: Iterable[int] | None = None, *, timeout: float = 2.0) -> None:
        self.wait(self.start_stop(legs, timeout=timeout))

    def wait_ready(self, timeout: float) -> BoardStatus:
        """Wait until every leg is steady (loose, holding or stopped); a fault raises."""
        deadline = time.monotonic() + timeout
        while True:
            status = self.poll()
            if status is not None:
                self.raise_for_faults()
                if status.ready and not self._ops:
                    return status
            if time.monotonic() >= deadline:
                states = ", ".join(s.state.name for s in status.legs) if status else "no status"
                raise LegTimeout(f"legs not ready within {timeout:g} s ({states})")
            self._wait_readable(0.02)

    def query(self, timeout: float = 1.0) -> BoardStatus:
        """Ask for a fresh status and wait for it."""
        before = self.status.received_at if self.status else 0.0
        self._send(messages.Query())
        deadline = time.monotonic() + timeout
        while True:
            status = self.poll()
            if status is not None and status.received_at > before:
                return status
            if time.monotonic() >= deadline:
                raise LegTimeout(f"no status within {timeout:g} s of QUERY")
            self._wait_readable(0.02)

    def raise_for_faults(self) -> None:
        """Raise :class:`LegFault` for the first faulted leg in the latest status."""
        if self.status is not None:
            for s in self.status.faults:
                raise LegFault(s.leg, int(s.fault), FAULT_TEXT[s.fault])

    # ---- internals --------------------------------------------------------------------
    def _legs(self, legs: Iterable[int]) -> tuple[int, ...]:
        out = tuple(sorted(set(legs)))
        if not out or not all(isinstance(i, int) and 0 <= i < N_LEGS for i in out):
            raise ValueError(f"legs must be indices 0..{N_LEGS - 1}, got {list(legs)}")
        return out

    def _start(
        self,
        kind: str,
        msg: messages.Message,
        legs: tuple[int, ...],
        targets: dict[int, float],
        target_ma: dict[int, int],
        timeout: float,
        tolerance: float,
    ) -> Operation:
        if self._ser is None:
            raise BoardDisconnected(f"leg board port {self.port} is not open")
        if self.status is not None:
            start = self.status.board_time_s
        else:
            start = self.info.board_time_s if self.info else 0.0
        op = Operation(
            kind,
            legs,
            {k: targets[k] for k in legs if k in targets},
            target_ma,
            time.monotonic() + timeout,
            tolerance,
            start,
        )
        for other in self._ops:
            if set(other.legs) & set(legs):
                other.fail(LegBoardError(f"{other.kind} on legs {other.legs} superseded by {kind}"))
        self._ops = [o for o in self._ops if not o.done] + [op]
        seq = self._send(msg)
        self._pending[seq] = _Pending(codec.encode(msg, seq), messages.type_of(msg), op, time.monotonic())
        return op

    def _send(self, msg: messages.Message) -> int:
        seq = self._seq
        self._seq = (self._seq + 1) & 0xFF
        self._write(codec.encode(msg, seq))
        return seq

    def _write(self, data: bytes) -> None:
        if self._ser is None:
            raise BoardDisconnected(f"leg board port {self.port} is not open")
        try:
            self._ser.write(data)
        except serial.SerialTimeoutException:
            raise LegTimeout(f"leg board port {self.port}: write timed out") from None
        except (serial.SerialException, OSError) as exc:
            raise BoardDisconnected(f"leg board port {self.port}: {exc}") from None

    def _read(self) -> list[codec.Frame]:
        if self._ser is None:
            raise BoardDisconnected(f"leg board port {self.port} is not open")
        try:
            data = self._ser.read(4096)
        except (serial.SerialException, OSError) as exc:
            raise BoardDisconnected(f"leg board port {self.port}: {exc}") from None
        frames = self.decoder.feed(data) if data else []
        for frame in frames:
            self._last_good = time.monotonic()
            self._rejects_at_good = self.decoder.rejects.total()
            self._handle(frame)
        return frames

    def _handle(self, frame: codec.Frame) -> None:
        msg = frame.message
        if isinstance(msg, messages.Status):
            self.status = self._convert(msg)
            for op in self._ops:
                op.update(self.status, self.calibration)
        elif isinstance(msg, messages.Ack | messages.Nak):
            pending = self._pending.get(msg.cmd_seq)
            if pending is None or pending.msg_type != msg.cmd_type:
                return
            del self._pending[msg.cmd_seq]
            if pending.op is None:
                return
            if isinstance(msg, messages.Ack):
                pending.op.acknowledge(self.status)
            else:
                name = MsgType(msg.cmd_type).name
                pending.op.fail(CommandRejected(name, msg.code, NAK_TEXT.get(msg.code, "?")))

    def _resend(self, now: float) -> None:
        for seq, p in list(self._pending.items()):
            if p.op is not None and p.op.done:
                del self._pending[seq]
            elif now - p.sent_at >= self.ack_timeout:
                if p.tries > self.ack_retries:
                    del self._pending[seq]
                    if p.op is not None:
                        p.op.fail(
                            LegTimeout(
                                f"no acknowledgement of {MsgType(p.msg_type).name} after {p.tries} tries"
                            )
                        )
                    continue
                self._write(p.data)
                p.sent_at = now
                p.tries += 1

    def _convert(self, msg: messages.Status) -> BoardStatus:
        legs = []
        for i, r in enumerate(msg.legs):
            if r.state in (LegState.TIGHTENING, LegState.HOLDING):
                torque: float | None = self.calibration.torque(i, r.current_ma)
            elif r.state is LegState.LOOSE:
                torque = 0.0
            else:
                torque = None
            legs.append(
                LegStatus(i, r.state, r.fault, r.current_ma, r.target_ma, r.angle_cdeg / 100.0, torque)
            )
        return BoardStatus(msg.board_time_ms / 1000.0, tuple(legs), time.monotonic(), msg.last_cmd_seq)

    def _silence_error(self, what: str) -> LegBoardError:
        rejected = self.decoder.rejects.total() - self._rejects_at_good
        if rejected:
            counts = ", ".join(f"{k} {v}" for k, v in self.decoder.rejects.as_dict().items() if v)
            return ProtocolError(
                f"leg board on {self.port}: {what}; {rejected} frames rejected and none accepted ({counts})"
            )
        return LegTimeout(f"leg board on {self.port} silent: {what}")

    def _wait_readable(self, timeout: float) -> None:
        if self._ser is None or timeout <= 0:
            return
        with contextlib.suppress(OSError, ValueError):  # the next read reports a failure
            select.select([self._ser.fileno()], [], [], timeout)
