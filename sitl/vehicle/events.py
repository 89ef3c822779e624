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
from typing import TYPE_CHECKING

from sitl.vehicle import esc

if TYPE_CHECKING:
    from sitl.vehicle.vehicle import Vehicle

REARM_CLEARANCE_M = 0.3


class Events:
    def __init__(self) -> None:
        self.clear = False  # the vehicle has been clear of the surface since the last contact
        self.stopped = False
        self.reversing = False

    def _send(self, v: Vehicle, name: str, t: float, value: float) -> None:
        from sitl.vehicle.mavlink_endpoints import mavlink

        v.links.send(mavlink.MAVLink_named_value_float_message(int(t * 1000), name.encode(), float(value)))

    def after_physics_step(self, v: Vehicle) -> None:
        """Called after every physics step."""
        st = v.stepper
        if not self.clear:
            self.clear = not st.in_contact() and st.clearance() >= REARM_CLEARANCE_M
            return
        if not st.in_contact():
            return
        self.clear = False
        t = v.t
        b = v._world_body()
        self._send(v, "EV_CONTACT", t, t)
        self._send(v, "CT_VZ", t, -b.vz)
        self._send(v, "CT_VX", t, b.vx)
        self._send(v, "CT_PITCH", t, math.degrees(b.pitch))
        self._send(v, "CT_RATE", t, math.degrees(b.pitch_rate))
        self._send(v, "CT_SLOPE", t, st.slope_deg)

    def after_outputs(self, v: Vehicle, pwm: list[int]) -> None:
        """Called once per control tick with the four outputs sent to the ESCs."""
        cmd = [esc.pwm_to_command(p) for p in pwm[:4]]
        stopped = v.armed and all(c == 0.0 for c in cmd)
        reversing = v.armed and all(c < 0.0 for c in cmd)
        if stopped and not self.stopped:
            self._send(v, "EV_STOP", v.t, v.t)
        if reversing and not self.reversing:
            self._send(v, "EV_RVT", v.t, v.t)
        self.stopped, self.reversing = stopped, reversing
