"""Feed the simulated leg board from the vehicle: friction torques in, joint angles out.

At about 50 Hz vehicle time: read the board's friction torque per real joint (legs 0, 1 uphill
pair; 2, 3 downhill pair) and set the Stepper's planar pair torques (the mean of each pair);
while well clear of the surface (5 cm) the board's joint angles become the legs' angles (the
springs reset them); while in contact the Stepper's joint angles are written back to the board.
Between the two (a foot bouncing off during a landing) neither: resetting the legs then would
cut into the landing the physics is computing.

A board started with ``--clock external`` runs on the vehicle's clock: each exchange first
advances it to the vehicle's time (one round trip, the vehicle waits for the reply), so board
and vehicle time stay together whatever the machine's load. A board on the wall clock is only
read and written, as before.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Protocol

from slopelander.model.stepper import Stepper
from slopelander_sitl.legboard.control import TIMEOUT_S, BoardControl, ControlError

PERIOD_S = 0.02
CLEAR_M = 0.05  # the board's angles reach the physics only this far clear of the surface


class LegsHost(Protocol):
    """What the link needs from a simulator: its clock, its model and a way to report."""

    stepper: Stepper

    @property
    def t(self) -> float: ...

    def statustext(self, text: str, severity: int = 6) -> None: ...


class LegsLink:
    def __init__(self, control_path: Path, period_s: float = PERIOD_S) -> None:
        if not (period_s > 0 and math.isfinite(period_s)):
            raise ValueError(f"leg board period must be a positive number of seconds, got {period_s!r}")
        # a simulator in lock-step with the board waits for each exchange: on a loaded machine
        # (several simulations on 2 cores) one can take seconds, and a timeout here ends the
        # simulated legs for good (``error``), which reads as a silent board to the companion
        self.ctl = BoardControl(control_path, timeout=TIMEOUT_S)
        self.period_s = period_s
        try:
            #: whether the board follows the vehicle's clock (``--clock external``)
            self.external = self.ctl.state().get("clock") == "external"
        except BaseException:
            self.ctl.close()
            raise
        self.next_t = 0.0
        self.error: str | None = None

    def update(self, v: LegsHost) -> None:
        if v.t < self.next_t or self.error is not None:
            return
        self.next_t = v.t + self.period_s
        try:
            legs = (self.ctl.advance(v.t) if self.external else self.ctl.state())["legs"]
            tau = [float(lg["torque_nm"]) for lg in legs]
            up = 0.5 * (tau[0] + tau[1])
            down = 0.5 * (tau[2] + tau[3])
            v.stepper.set_friction(min(10.0, max(0.0, up)), min(10.0, max(0.0, down)))
            st = v.stepper
            if st.in_contact():
                a_up, a_down = st.joint_angles_deg()
                self.ctl.set_joint_angles([a_up, a_up, a_down, a_down])
            elif st.clearance() > CLEAR_M:
                ang = [float(lg["angle_deg"]) for lg in legs]
                lo, hi = st.model.params.angle_min_deg, st.model.params.angle_max_deg
                a_up = min(hi, max(lo, 0.5 * (ang[0] + ang[1])))
                a_down = min(hi, max(lo, 0.5 * (ang[2] + ang[3])))
                st.set_leg_angles(a_up, a_down)
        except (ControlError, KeyError, TypeError, ValueError) as exc:
            self.error = str(exc)
            v.statustext(f"Legs link lost: {exc}"[:50], 3)

    def close(self) -> None:
        self.ctl.close()
