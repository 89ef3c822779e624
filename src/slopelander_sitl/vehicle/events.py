"""Measurement events: what a latency benchmark or a flight test needs and cannot see on a real
vehicle (the moment of ground contact, the moment the outputs change), sent as NAMED_VALUE_FLOAT.

A real ArduCopter sends none of these; a companion that does not know them ignores them. Each
event's ``value`` is the vehicle time of the event in seconds (float, sub-millisecond: the physics
step), ``time_boot_ms`` the same time in whole milliseconds:

- ``EV_CONTACT``: the first physics step with a foot (or any point) on the surface after the
  vehicle was at least ``REARM_CLEARANCE_M`` clear of it; sent with the body's state at that step:
  ``CT_VZ`` (vertical speed, m/s, positive down), ``CT_VX`` (horizontal speed, m/s, world +x =
  downhill), ``CT_PITCH`` (deg, nose up positive), ``CT_RATE`` (deg/s), ``CT_SLOPE`` (deg, the
  surface the physics has).
- ``EV_STOP``: the first control tick, while armed, whose four outputs all lie in the ESCs' stop
  band (1500 ± 30 µs) after any did not.
- ``EV_RVT``: the first control tick, while armed, whose four outputs all command reverse
  (below the stop band) after any did not.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from slopelander_sitl.vehicle import esc

if TYPE_CHECKING:
    from slopelander.model.stepper import BodyState as Body
    from slopelander.model.stepper import Stepper

REARM_CLEARANCE_M = 0.3


class Events:
    """Detects the events; ``send(name, t, value)`` reports each one (the simulated vehicle as
    NAMED_VALUE_FLOAT, the JSON physics into a file: ArduCopter has no channel for them)."""

    def __init__(self, send: Callable[[str, float, float], None]) -> None:
        self.send = send
        self.clear = False  # the vehicle has been clear of the surface since the last contact
        self.stopped = False
        self.reversing = False
        self._last_outputs: tuple | None = None  # (armed, four outputs) of the last call

    def after_physics_step(self, stepper: Stepper, t: float, world_body: Callable[[], Body]) -> None:
        """Called after every physics step; ``world_body()`` gives the body in world coordinates,
        read only at a contact (1,200 times a simulated second, the body is rarely needed)."""
        st = stepper
        if not self.clear:
            self.clear = not st.in_contact() and st.clearance() >= REARM_CLEARANCE_M
            return
        if not st.in_contact():
            return
        self.clear = False
        body = world_body()
        self.send("EV_CONTACT", t, t)
        self.send("CT_VZ", t, -body.vz)
        self.send("CT_VX", t, body.vx)
        self.send("CT_PITCH", t, math.degrees(body.pitch))
        self.send("CT_RATE", t, math.degrees(body.pitch_rate))
        self.send("CT_SLOPE", t, st.slope_deg)

    def after_outputs(self, t: float, armed: bool, pwm: Sequence[int]) -> None:
        """Called once per control tick with the four outputs sent to the ESCs."""
        key = (armed, *pwm[:4])
        if key == self._last_outputs:
            return  # the same outputs give the same state, and an event only fires on a change
        self._last_outputs = key
        cmd = [esc.pwm_to_command(p) for p in pwm[:4]]
        stopped = armed and all(c == 0.0 for c in cmd)
        reversing = armed and all(c < 0.0 for c in cmd)
        if stopped and not self.stopped:
            self.send("EV_STOP", t, t)
        if reversing and not self.reversing:
            self.send("EV_RVT", t, t)
        self.stopped, self.reversing = stopped, reversing
