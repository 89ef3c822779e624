"""ArduCopter-style land detector: throttle at its floor, filtered acceleration under 1 m/s^2
and descent slower than 1 m/s, all held for 1 s, then landed (maybe_landed after half that)."""

from __future__ import annotations

import math

HOLD_S = 1.0


class LandDetector:
    def __init__(self) -> None:
        self.landed = True  # the vehicle starts on the pad
        self._held = 0.0
        self._acc = 0.0

    @property
    def maybe_landed(self) -> bool:
        return self.landed or self._held >= 0.5 * HOLD_S

    def update(
        self,
        dt: float,
        armed: bool,
        throttle_at_floor: bool,
        accel_ned: tuple[float, float],
        climb_rate: float,
    ) -> None:
        if not armed:
            self.landed = True
            self._held = HOLD_S
            return
        a = math.hypot(*accel_ned)
        self._acc += min(1.0, dt / 1.0) * (a - self._acc)  # 1 Hz low-pass, as ArduCopter's
        if throttle_at_floor and self._acc < 1.0 and abs(climb_rate) < 1.0:
            self._held = min(HOLD_S, self._held + dt)
        else:
            self._held = 0.0
            if not throttle_at_floor:
                self.landed = False
        if self._held >= HOLD_S:
            self.landed = True
