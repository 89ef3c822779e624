"""Client of the simulated board's control channel (simulation only).

This is the API the vehicle simulator uses to feed landing compression into the board and
read back the friction torques, and the one tests use to inject faults at run time::

    with BoardControl("/tmp/legs.ctl") as ctl:
        ctl.set_joint_angles([30.0, 30.5, None, None])   # degrees; None = leave alone
        torques = ctl.friction_torques()                  # N·m per leg
        ctl.inject("overcurrent", leg=2)

A board started with ``--clock external`` stands still until ``advance`` feeds it time.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Sequence
from pathlib import Path

#: wall seconds for one exchange with the board's control socket: the board is a relay and a
#: firmware process, and on a loaded machine (several simulations on 2 cores, or two busy
#: processes beside the suite) one exchange has taken more than 2 s
TIMEOUT_S = 10.0


class ControlError(RuntimeError):
    """The board refused a control request or the channel failed."""


class BoardControl:
    """A connection to one board's control socket; every call has a timeout."""

    def __init__(self, path: str | Path, timeout: float = TIMEOUT_S) -> None:
        self.path = str(path)
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock.settimeout(timeout)
        try:
            self._sock.connect(self.path)
        except OSError as exc:
            self._sock.close()
            raise ControlError(f"cannot connect to {self.path}: {exc}") from None
        self._buf = b""

    def close(self) -> None:
        self._sock.close()

    def __enter__(self) -> BoardControl:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def request(self, **req: object) -> dict:
        try:
            self._sock.sendall(json.dumps(req).encode() + b"\n")
            while b"\n" not in self._buf:
                chunk = self._sock.recv(65536)
                if not chunk:
                    raise ControlError("board closed the control channel")
                self._buf += chunk
        except OSError as exc:
            raise ControlError(f"control channel {self.path}: {exc}") from None
        line, _, self._buf = self._buf.partition(b"\n")
        reply = json.loads(line)
        if not reply.get("ok"):
            raise ControlError(reply.get("error", "refused"))
        return reply

    def state(self) -> dict:
        """Board time and, per leg: state, fault, angle, friction torque, current, travel."""
        return self.request(op="state")

    def advance(self, to_s: float) -> dict:
        """Step an external-clock board's time up to ``to_s`` (s), then its :meth:`state`."""
        return self.request(op="advance", to_s=float(to_s))

    def set_joint_angles(self, angles_deg: Sequence[float | None]) -> float:
        """Set joint angles (degrees, 0 = fully compressed … 37.5 = extended); board time."""
        return self.request(op="set_angles", deg=list(angles_deg))["time_s"]

    def friction_torques(self) -> list[float]:
        """Friction torque each joint holds now, N·m (per real joint)."""
        return [leg["torque_nm"] for leg in self.state()["legs"]]

    def inject(self, kind: str, leg: int | None = None, rate: float | None = None) -> None:
        """Inject ``stuck``/``slip``/``overcurrent`` (on ``leg``), ``silent``,
        ``corrupt`` (byte ``rate``) or ``unplug``."""
        req: dict = {"op": "fault", "kind": kind}
        if leg is not None:
            req["leg"] = leg
        if rate is not None:
            req["rate"] = rate
        self.request(**req)

    def clear_faults(self) -> None:
        self.request(op="clear")

    def quit(self) -> None:
        self.request(op="quit")
