"""Errors of the leg board, typed so the landing controller can act on each one.

All derive from :class:`LegBoardError` (itself a :class:`SlopelanderError`), so a caller
that only wants "the legs are not ready" catches one type, while a state machine can tell
a slow leg (:class:`LegNotConverged`) from a broken one (:class:`LegFault`) or a lost link
(:class:`LegTimeout`, :class:`BoardDisconnected`).
"""

from __future__ import annotations

from slopelander.errors import SlopelanderError


class LegBoardError(SlopelanderError):
    """Anything that went wrong between the companion and the leg board."""


class LegTimeout(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """The board did not answer, or sent nothing, within the allowed time."""


class BoardDisconnected(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """The serial port failed or vanished (cable pulled, board reset)."""


class ProtocolError(LegBoardError):
    """Bytes arrive but make no valid frames, or the board speaks another version."""


class CommandRejected(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """The board answered a command with NAK."""

    def __init__(self, command: str, code: int, text: str) -> None:
        self.command = command
        self.code = code
        self.text = text
        super().__init__(f"leg board refused {command}: {text} (NAK code {code})")


class LegFault(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """A leg reports a fault; its motor is off until it is loosened."""

    def __init__(self, leg: int, code: int, text: str) -> None:
        self.leg = leg
        self.code = code
        self.text = text
        super().__init__(f"leg {leg} fault {code} ({text})")


class LegNotConverged(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """A leg did not reach its target within the deadline.

    ``target`` and ``achieved`` are in the unit of the operation (N·m for friction,
    degrees for angles); ``results`` holds every leg's outcome of the same operation.
    """

    def __init__(
        self,
        leg: int,
        target: float,
        achieved: float,
        unit: str = "N·m",
        detail: str = "",
        results: dict | None = None,
    ) -> None:
        self.leg = leg
        self.target = target
        self.achieved = achieved
        self.unit = unit
        self.results = results or {}
        extra = f" ({detail})" if detail else ""
        super().__init__(
            f"leg {leg} did not converge: wanted {target:.3g} {unit}, reached {achieved:.3g} {unit}{extra}"
        )


class WriteQueueFull(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """The port has not taken the queued bytes and the driver's outgoing queue is full.

    The board is not reading (stalled or wedged); nothing was queued by the call that raised.
    """


class OperationSuperseded(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """A newer operation on some of the same legs replaced this one before it finished."""

    def __init__(self, kind: str, legs: tuple[int, ...], by: str) -> None:
        self.kind = kind
        self.legs = legs
        self.by = by
        super().__init__(f"{kind} on legs {list(legs)} superseded by {by}")


class OperationCancelled(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """The caller cancelled the operation; the driver no longer follows it."""


class BoardReconnected(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """The connection was reset (reconnect): operations started before it cannot be followed."""


class OperationPending(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """``result()`` asked of an operation that has not finished yet."""


class AngleOutOfRange(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """A leg angle outside what the legs (and the protocol) can hold."""


class TorqueOutOfRange(LegBoardError):  # noqa: N818 (names the landing controller reads)
    """A friction torque the leg's calibration does not cover."""


class CalibrationError(LegBoardError):
    """A calibration file that cannot be used; names the file and the field."""

    def __init__(self, file: str, field: str, message: str) -> None:
        self.file = file
        self.field = field
        super().__init__(f"calibration file {file}: field {field}: {message}")
