"""Companion-side driver of the leg board (pyserial).

Two ways to use it. A landing state machine starts an operation and polls it each tick::

    op = board.start_presets(uphill_nm=1.7, downhill_nm=2.3, timeout=20.0)
    ...                      # every tick:
    board.poll()             # reads the port; raises on a lost or garbled link
    results = op.check()     # None while running; per-leg results; raises a typed error

A script calls the blocking forms, which do the same with a deadline::

    with LegBoard.open("/dev/ttyACM0", 115200) as board:
        board.set_torques(uphill=1.7, downhill=2.3, timeout=20.0)

Nothing on the polling path blocks: outgoing frames go to a bounded queue that ``poll()``
hands to the port as fast as the port takes them (a full queue is :class:`WriteQueueFull`).
Every timeout is measured on the injected ``clock`` (a callable returning seconds,
``time.monotonic`` by default): the landing controller passes its autopilot-following clock,
tests a simulated one. The blocking forms wait on the port with ``select`` but their deadlines
too are on that clock, so give them a clock that advances on its own. Nothing here waits
without a deadline.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import os
import select
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import serial

from slopelander.legs import codec, messages
from slopelander.legs.calibration import Calibration, load_calibration
from slopelander.legs.errors import (
    BoardDisconnected,
    BoardReconnected,
    CommandRejected,
    LegBoardError,
    LegFault,
    LegNotConverged,
    LegTimeout,
    OperationCancelled,
    OperationPending,
    OperationSuperseded,
    ProtocolError,
    WriteQueueFull,
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
MAX_QUEUE_BYTES = 4096  # about 200 commands: far more than a landing sends between two polls
#: bytes a read that waits for what the kernel has in flight takes at most (:meth:`LegBoard._read`)
CHUNK = 4096
#: a KEEPALIVE goes out when nothing else was sent for this long (driver clock or wall time, which
#: ever comes first): the board stops holding its motors after 10 s of silence
KEEPALIVE_S = 0.1


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
    #: the board's own id (16 hex digits): a measured calibration names the board it was made on
    board_id: str = ""
    #: the firmware's version, "major.minor"
    firmware: str = ""

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
    """The latest STATUS, in engineering units, with the driver-clock time it arrived."""

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


class Operation:
    """A command in flight and the per-leg convergence of its effect.

    A handle the caller reads and never writes: :attr:`done`, :meth:`result`, :meth:`exception`,
    :meth:`cancel` (and :meth:`check`, None while running). Only the driver advances it, from
    the board's reports, so a state machine cannot corrupt it by accident.
    """

    __slots__ = (
        "_acked",
        "_deadline",
        "_error",
        "_kind",
        "_legs",
        "_results",
        "_samples",
        "_settled_at",
        "_start_board_s",
        "_target_ma",
        "_targets",
        "_tolerance",
    )

    def __init__(
        self,
        kind: str,
        legs: tuple[int, ...],
        targets: dict[int, float],
        target_ma: dict[int, int],
        deadline: float,
        tolerance: float,
        start_board_s: float,
    ) -> None:
        self._kind = kind
        self._legs = tuple(legs)
        self._targets = dict(targets)
        self._target_ma = dict(target_ma)
        self._deadline = deadline
        self._tolerance = tolerance
        self._start_board_s = start_board_s
        self._acked = False
        self._error: LegBoardError | None = None
        self._results: dict[int, LegResult] = {}
        self._samples: dict[int, collections.deque] = {}
        self._settled_at: dict[int, float] = {}

    def __repr__(self) -> str:
        state = "failed" if self._error else "done" if self.done else "running"
        return f"<Operation {self._kind} legs={list(self._legs)} {state}>"

    # ---- what the caller reads ----------------------------------------------------------
    @property
    def kind(self) -> str:
        """friction, current, angle, loosen or stop."""
        return self._kind

    @property
    def legs(self) -> tuple[int, ...]:
        return self._legs

    @property
    def targets(self) -> Mapping[int, float]:
        return MappingProxyType(self._targets)

    @property
    def target_ma(self) -> Mapping[int, int]:
        return MappingProxyType(self._target_ma)

    @property
    def deadline(self) -> float:
        """When it fails if not finished, in the driver's clock (s)."""
        return self._deadline

    @property
    def acked(self) -> bool:
        """Whether the board has acknowledged the command."""
        return self._acked

    @property
    def results(self) -> Mapping[int, LegResult]:
        """The legs that converged so far."""
        return MappingProxyType(self._results)

    @property
    def done(self) -> bool:
        return self._error is not None or len(self._results) == len(self._legs)

    @property
    def cancelled(self) -> bool:
        return isinstance(self._error, OperationCancelled)

    @property
    def error(self) -> LegBoardError | None:
        """Same as :meth:`exception`."""
        return self._error

    def exception(self) -> LegBoardError | None:
        """The typed error it failed with, or None (running or succeeded)."""
        return self._error

    def result(self) -> dict[int, LegResult]:
        """Per-leg results; raises its error if it failed, :class:`OperationPending` if running."""
        results = self.check()
        if results is None:
            raise OperationPending(f"{self._kind} on legs {list(self._legs)} is still running")
        return results

    def check(self) -> dict[int, LegResult] | None:
        """Per-leg results once every leg converged; None while running; raises on failure."""
        if self._error is not None:
            raise self._error
        if len(self._results) == len(self._legs):
            return dict(sorted(self._results.items()))
        return None

    def cancel(self) -> bool:
        """Stop following it (no more re-sends; it fails with :class:`OperationCancelled`).

        Returns False if it had already finished. A command the board already took is not
        undone: to stop the motors, start a stop; to free the legs, a loosen.
        """
        if self.done:
            return False
        self._fail(OperationCancelled(f"{self._kind} on legs {list(self._legs)} cancelled"))
        return True

    # ---- the driver's side --------------------------------------------------------------
    def _acknowledge(self, status: BoardStatus | None) -> None:
        """The board took the command: board time counts from its latest status."""
        self._acked = True
        if status is not None:
            self._start_board_s = status.board_time_s

    def _fail(self, error: LegBoardError) -> None:
        if not self.done:
            self._error = error

    def _shift(self, offset: float) -> None:
        self._deadline += offset

    def _update(self, status: BoardStatus, calibration: Calibration) -> None:
        if self.done or not self._acked:
            return
        for leg in self._legs:
            if leg in self._results:
                continue
            s = status.legs[leg]
            if s.state is LegState.FAULT:
                self._fail(LegFault(leg, int(s.fault), FAULT_TEXT[s.fault]))
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
                    self._results[leg] = result

    def _expire(self, status: BoardStatus | None, calibration: Calibration) -> None:
        """Past the deadline: fail with the first leg that has not converged."""
        if self.done:
            return
        if not self._acked:
            self._fail(LegTimeout(f"{self._kind}: the board never acknowledged the command"))
            return
        partial = dict(self._results)
        for leg in self._legs:
            if leg not in partial and status is not None:
                partial[leg] = self._result(leg, status, calibration, final=True)
        for leg in self._legs:
            if leg not in self._results:
                r = partial.get(leg)
                unit = {"friction": "N·m", "current": "mA"}.get(self._kind, "°")
                state = status.legs[leg].state.name if status else "unknown"
                self._fail(
                    LegNotConverged(
                        leg,
                        self._targets.get(leg, float("nan")),
                        r.achieved if r else float("nan"),
                        unit=unit,
                        detail=f"state {state}, current {r.current_ma:.0f} mA of "
                        f"{self._target_ma.get(leg, 0)} mA"
                        if r
                        else "no status",
                        results=partial,
                    )
                )
                return

    def _counts(self, s: LegStatus) -> bool:
        """Whether this status is one of the settled samples the leg needs."""
        if self._kind in ("friction", "current"):
            if self._target_ma[s.leg] == 0:
                return s.state is LegState.LOOSE
            return s.state is LegState.HOLDING and s.target_ma == self._target_ma[s.leg]
        if self._kind == "stop":
            return s.state is LegState.STOPPED
        return s.state is LegState.LOOSE  # loosen, angle

    def _result(self, leg: int, status: BoardStatus, cal: Calibration, final: bool) -> LegResult:
        s = status.legs[leg]
        samples = list(self._samples.get(leg, ()))
        current = sum(c for c, _ in samples) / len(samples) if samples and not final else float(s.current_ma)
        angles = [a for _, a in samples] or [s.angle_deg]
        angle = angles[-1]
        target = self._targets.get(leg)
        if self._kind == "friction":
            achieved = cal.torque(leg, current) if self._target_ma[leg] else 0.0
            ok = target is not None and abs(achieved - target) <= self._tolerance
        elif self._kind == "current":  # held on its target: the board's band is the tolerance
            achieved = current
            ok = True
        elif self._kind == "angle":
            achieved = angle
            ok = target is not None and abs(angle - target) <= self._tolerance
        else:  # loosen, stop: settled when the angle stops moving
            achieved = angle
            ok = max(angles) - min(angles) <= self._tolerance
        return LegResult(
            leg,
            ok and not final,
            target,
            achieved,
            current,
            self._target_ma.get(leg),
            angle,
            self._settled_at.get(leg, status.board_time_s) - self._start_board_s,
        )


@dataclass
class _Pending:
    data: bytes
    msg_type: int
    op: Operation | None
    sent_at: float
    tries: int = 1
    first_at: float | None = None  # when it was first sent (sent_at moves with each try)

    def __post_init__(self) -> None:
        if self.first_at is None:
            self.first_at = self.sent_at


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
        clock: Callable[[], float] = time.monotonic,
        max_queue_bytes: int = MAX_QUEUE_BYTES,
        keepalive_s: float = KEEPALIVE_S,
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
        self.clock = clock
        self.max_queue_bytes = max_queue_bytes
        self._outq = bytearray()
        self._statuses = 0  # reports received (a clock that stands still cannot order them)
        self._ser: serial.Serial | None = None
        self._seq = 0
        self._pending: dict[int, _Pending] = {}
        self._ops: list[Operation] = []
        self._last_good = 0.0
        self._rejects_at_good = 0
        self.keepalive_s = keepalive_s
        self._sent_at = (-float("inf"), -float("inf"))  # (driver clock, wall) of the last frame

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
        """Open the port (non-blocking) and handshake within ``timeout`` s of the clock."""
        try:
            self._ser = self._serial_factory(self.port, self.baud, timeout=0, write_timeout=0, exclusive=True)
            self._ser.reset_input_buffer()
            with contextlib.suppress(AttributeError, OSError, ValueError):
                os.set_blocking(self._ser.fileno(), False)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise BoardDisconnected(f"cannot open leg board port {self.port}: {exc}") from None
        deadline = self.clock() + timeout
        hello = messages.Hello(messages.PROTOCOL_VERSION, self.status_period_ms)
        self._write(b"\x00")
        next_try = -float("inf")
        while True:
            now = self.clock()
            last = now >= deadline  # the last look: what the kernel holds too, as before "silent"
            if now >= next_try:
                seq = self._send(hello)
                next_try = now + self.ack_timeout
            for frame in self._read(in_flight=last):
                msg = frame.message
                if isinstance(msg, messages.HelloReply):
                    if msg.version != messages.PROTOCOL_VERSION:
                        raise self._version_error(msg.version)
                    if msg.legs != N_LEGS:
                        raise ProtocolError(
                            f"leg board on {self.port} reports {msg.legs} legs; slopelander drives "
                            f"{N_LEGS} (legs 0..{N_LEGS - 1}, docs/legs-build.md)"
                        )
                    info = BoardInfo(
                        msg.version,
                        msg.legs,
                        msg.capabilities,
                        msg.max_payload,
                        msg.board_time_ms / 1000.0,
                        msg.board_id_hex,
                        msg.firmware_text,
                    )
                    self.calibration.check_board(info.board_id)
                    self.info = info
                    self._last_good = self.clock()
                    self._rejects_at_good = self.decoder.rejects.total()
                    return self.info
                if isinstance(msg, messages.Nak) and msg.cmd_seq == seq:
                    if msg.code == messages.NakCode.BAD_VERSION:
                        raise ProtocolError(
                            f"leg board on {self.port} does not speak protocol version "
                            f"{messages.PROTOCOL_VERSION} (it refused HELLO): flash the firmware "
                            "of this release (docs/legs-build.md)"
                        )
                    raise ProtocolError(
                        f"leg board on {self.port} refused HELLO: {NAK_TEXT.get(msg.code, msg.code)}"
                    )
            if self.decoder.foreign_version is not None:
                raise self._version_error(self.decoder.foreign_version)
            if last:
                raise self._silence_error(f"no HELLO_REPLY within {timeout:g} s")
            self._flush()
            self._wait_readable(min(next_try, deadline, self.clock() + 0.05) - self.clock())

    def _version_error(self, version: int) -> ProtocolError:
        return ProtocolError(
            f"leg board on {self.port} speaks protocol version {version}, this driver "
            f"{messages.PROTOCOL_VERSION}: flash the firmware of this release (docs/legs-build.md)"
        )

    def reconnect(self, timeout: float = 2.0) -> BoardInfo:
        """Start afresh with a board that came back (or was reset): close the port, fail every
        running operation with :class:`BoardReconnected`, drop unsent and unacknowledged
        commands, reset the decoder and the sequence numbers, forget the last status, then
        open and handshake again."""
        error = BoardReconnected(f"leg board on {self.port} reconnected: the operation was dropped")
        for op in self._ops:
            op._fail(error)
        self._ops.clear()
        for p in self._pending.values():
            if p.op is not None:
                p.op._fail(error)
        self._pending.clear()
        self._outq.clear()
        self.decoder = codec.Decoder()
        self._seq = 0
        self.status = None
        self.info = None
        self.close()
        return self.connect(timeout)

    def set_clock(self, clock: Callable[[], float]) -> None:
        """Measure every timeout on ``clock`` from now on; running deadlines keep their length."""
        offset = clock() - self.clock()
        self.clock = clock
        self._shift(offset)

    @property
    def connected(self) -> bool:
        """Whether the port is open (False after :meth:`close`, or before a reconnect)."""
        return self._ser is not None

    def unobserved(self, seconds: float) -> None:
        """Tell the driver that ``seconds`` of its clock went by while nobody could watch the
        board on it (an autopilot clock that stood still during a MAVLink outage, then jumped):
        running deadlines and the silence reference move on with it, so the jump is not taken
        for a silent board or a leg that failed to converge."""
        if seconds > 0:
            self._shift(seconds)

    def _shift(self, offset: float) -> None:
        """Move every running deadline and reference time by ``offset`` seconds."""
        self._last_good += offset
        for p in self._pending.values():
            p.sent_at += offset
            p.first_at += offset
        for op in self._ops:
            op._shift(offset)
        if self.status is not None:
            self.status = dataclasses.replace(self.status, received_at=self.status.received_at + offset)

    def catch_up(self) -> None:
        """Read what the kernel still has in flight from the board, waiting for it (see
        :meth:`_read`): for a caller that waits anyway, a lock-stepped simulator held until the
        board is heard. Costs nothing when nothing is in flight; errors are the next poll's."""
        if self._ser is not None:
            with contextlib.suppress(LegBoardError):
                self._read(in_flight=True)

    def accounted_until(self) -> float | None:
        """The time on this driver's clock up to which the board is accounted for: its newest
        good frame's arrival, or the first sending of a command it has not yet answered if
        that is older (None while the port is closed: nothing to wait for). A simulation that
        feeds the board its time and waits for the companion (the lock-step echo, a simulated
        bench) does not run far past it: a loaded machine can hold a pseudo-terminal's bytes
        for seconds, which a real board's UART does not."""
        if self._ser is None:
            return None
        t = self._last_good
        for p in self._pending.values():
            t = min(t, p.first_at)
        return t

    @property
    def queued_bytes(self) -> int:
        """Bytes waiting for the port to take them."""
        return len(self._outq)

    def check_preset(
        self, uphill_nm: float, downhill_nm: float, uphill_angle_deg: float | None = None
    ) -> None:
        """Refuse a landing preset the legs' calibration cannot produce, before it is needed."""
        self.calibration.check_preset(uphill_nm, downhill_nm, uphill_angle_deg)

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
            self._flush()
            self._read()
            now = self.clock()
            self._resend(now)
            self._keepalive(now)
            if now - self._last_good > self.silence_timeout and not self._read(in_flight=True):
                raise self._silence_error(f"nothing for {self.silence_timeout:g} s")
        except LegBoardError as exc:
            for op in self._ops:
                op._fail(exc)
            self._ops.clear()
            raise
        for op in self._ops:
            if now > op.deadline:
                op._expire(self.status, self.calibration)
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
        # torque 0 is loosening, whatever the curve's lowest calibrated torque
        target_ma = {
            leg: self.calibration.current_for(leg, torques[leg]) if torques[leg] else 0 for leg in legs
        }
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

    def start_currents(self, currents_ma: Mapping[int, int], *, timeout: float = 20.0) -> Operation:
        """Start clamping legs to motor-current targets (mA) directly, bypassing the calibration:
        what measuring the calibration needs. Done when each leg holds its target."""
        legs = self._legs(currents_ma)
        target_ma = {leg: int(currents_ma[leg]) for leg in legs}
        for leg, ma in target_ma.items():
            if not 0 <= ma <= messages.MAX_TARGET_MA:
                raise ValueError(f"leg {leg}: current target {ma} mA outside 0..{messages.MAX_TARGET_MA}")
        currents = tuple(target_ma.get(i, 0) for i in range(N_LEGS))
        msg = messages.SetFriction(mask_of(legs), currents)
        return self._start(
            "current", msg, legs, {k: float(v) for k, v in target_ma.items()}, target_ma, timeout, 0.0
        )

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
        deadline = self.clock() + timeout
        while True:
            status = self.poll()
            if status is not None:
                self.raise_for_faults()
                if status.ready and not self._ops:
                    return status
            if self.clock() >= deadline:
                states = ", ".join(s.state.name for s in status.legs) if status else "no status"
                raise LegTimeout(f"legs not ready within {timeout:g} s ({states})")
            self._wait_readable(0.02)

    def query(self, timeout: float = 1.0) -> BoardStatus:
        """Ask for a fresh status and wait for it."""
        before = self._statuses
        self._send(messages.Query())
        deadline = self.clock() + timeout
        while True:
            status = self.poll()
            if status is not None and self._statuses > before:
                return status
            if self.clock() >= deadline:
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
        now = self.clock()
        op = Operation(
            kind,
            legs,
            {k: targets[k] for k in legs if k in targets},
            target_ma,
            now + timeout,
            tolerance,
            start,
        )
        seq = self._send(msg)  # a full queue raises here, before anything else changed
        for other in self._ops:
            if set(other.legs) & set(legs):
                other._fail(OperationSuperseded(other.kind, other.legs, f"{kind} on legs {list(legs)}"))
        self._ops = [o for o in self._ops if not o.done] + [op]
        self._pending[seq] = _Pending(codec.encode(msg, seq), messages.type_of(msg), op, now)
        return op

    def _send(self, msg: messages.Message) -> int:
        seq = self._seq
        self._write(codec.encode(msg, seq))
        self._seq = (self._seq + 1) & 0xFF
        self._sent_at = (self.clock(), time.monotonic())
        return seq

    def _keepalive(self, now: float) -> None:
        """Tell the board the companion is alive when nothing else went out for a while."""
        last_clock, last_wall = self._sent_at
        if self.info is None or self._ser is None:
            return
        due = now - last_clock >= self.keepalive_s or time.monotonic() - last_wall >= self.keepalive_s
        if due and len(self._outq) < self.max_queue_bytes // 2:  # a board not reading gets no more
            self._send(messages.Keepalive())

    def _write(self, data: bytes) -> None:
        """Queue ``data`` whole (or raise :class:`WriteQueueFull`), then flush what the port takes."""
        if self._ser is None:
            raise BoardDisconnected(f"leg board port {self.port} is not open")
        if len(self._outq) + len(data) > self.max_queue_bytes:
            self._flush()
            if len(self._outq) + len(data) > self.max_queue_bytes:
                raise WriteQueueFull(
                    f"leg board port {self.port}: {len(self._outq)} bytes not taken by the port "
                    f"(queue limit {self.max_queue_bytes}); the board is not reading"
                )
        self._outq += data
        self._flush()

    def _flush(self) -> None:
        """Hand the port as much of the queue as it takes now; never waits."""
        if self._ser is None or not self._outq:
            return
        try:
            try:
                fd = self._ser.fileno()
            except (AttributeError, NotImplementedError, serial.SerialException):
                n = self._ser.write(bytes(self._outq)) or 0  # write_timeout=0: non-blocking
            else:
                try:
                    n = os.write(fd, self._outq)
                except BlockingIOError:
                    n = 0
        except (serial.SerialException, OSError) as exc:
            raise BoardDisconnected(f"leg board port {self.port}: {exc}") from None
        del self._outq[:n]

    def _read(self, in_flight: bool = False) -> list[codec.Frame]:
        """What has arrived, without waiting: only the bytes the port says it holds are read.
        A poll or read of a Linux tty that finds nothing first waits for the kernel's worker to
        move bytes still in flight (``n_tty_poll`` -> ``tty_buffer_flush_work``): on a loaded
        machine that held this call 0.2-2.1 s (a pseudo-terminal, two busy processes on 2
        cores, 2026-12-07), and with it the companion's control loop. A hung-up port (an
        unplugged board) fails the count with EIO: that is the disconnect.

        ``in_flight``: when the port holds nothing, read anyway, which waits for bytes the
        kernel still has in flight: asked only where a wait is right, before the board is
        declared silent (a board whose bytes a loaded machine held is not failed for it) and in
        :meth:`catch_up`. A board that sent nothing costs no wait: nothing is in flight."""
        if self._ser is None:
            raise BoardDisconnected(f"leg board port {self.port} is not open")
        try:
            waiting = self._ser.in_waiting or (CHUNK if in_flight else 0)
            data = self._ser.read(waiting) if waiting else b""
        except (serial.SerialException, OSError) as exc:
            raise BoardDisconnected(f"leg board port {self.port}: {exc}") from None
        frames = self.decoder.feed(data) if data else []
        for frame in frames:
            self._last_good = self.clock()
            self._rejects_at_good = self.decoder.rejects.total()
            self._handle(frame)
        return frames

    def _handle(self, frame: codec.Frame) -> None:
        msg = frame.message
        if isinstance(msg, messages.Status):
            self.status = self._convert(msg)
            self._statuses += 1
            for op in self._ops:
                op._update(self.status, self.calibration)
        elif isinstance(msg, messages.Ack | messages.Nak):
            pending = self._pending.get(msg.cmd_seq)
            if pending is None or pending.msg_type != msg.cmd_type:
                return
            del self._pending[msg.cmd_seq]
            if pending.op is None:
                return
            if isinstance(msg, messages.Ack):
                pending.op._acknowledge(self.status)
            elif msg.code == messages.NakCode.FAULTED and self._faulted(pending.op.legs):
                pending.op._fail(self._faulted(pending.op.legs))  # say which fault, not only "faulted"
            else:
                name = MsgType(msg.cmd_type).name
                pending.op._fail(CommandRejected(name, msg.code, NAK_TEXT.get(msg.code, "?")))

    def _faulted(self, legs: Iterable[int]) -> LegFault | None:
        """The fault of the first of ``legs`` the latest status shows faulted."""
        if self.status is not None:
            for leg in legs:
                s = self.status.legs[leg]
                if s.state is LegState.FAULT:
                    return LegFault(leg, int(s.fault), FAULT_TEXT[s.fault])
        return None

    def _resend(self, now: float) -> None:
        for seq, p in list(self._pending.items()):
            if p.op is not None and p.op.done:
                del self._pending[seq]
            elif now - p.sent_at >= self.ack_timeout:
                if p.tries > self.ack_retries:
                    del self._pending[seq]
                    if p.op is not None:
                        p.op._fail(
                            LegTimeout(
                                f"no acknowledgement of {MsgType(p.msg_type).name} after {p.tries} tries"
                            )
                        )
                    continue
                if len(self._outq) + len(p.data) > self.max_queue_bytes:
                    continue  # the port is not taking bytes: re-send once it does
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
        return BoardStatus(msg.board_time_ms / 1000.0, tuple(legs), self.clock(), msg.last_cmd_seq)

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
