"""slopelander's vehicle physics as ArduPilot's JSON interface sees it: four motor outputs in,
one frame's sensors out.

The same parts as the simulated vehicle (``sitl.vehicle``): the model's Stepper on the
scenario's pad, roof and wind, the route-A ESC mapping (1500 us stopped, reversible, the model's
rotors holding the reversal delay), the IMU and rangefinder geometry, the scenario's sensor
faults and, when connected, the simulated leg board's torques. The planar model flies in the
north-down plane: model x is north, model z is up, model pitch is ArduPilot's pitch; roll, yaw
and east stay zero. Positions are from where the vehicle boots (ArduPilot's home).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from sitl.json_physics.protocol import Fdm
from sitl.vehicle import esc
from sitl.vehicle.events import Events
from sitl.vehicle.legs_link import LegsLink
from sitl.vehicle.scenario import Scenario
from sitl.vehicle.sensors import Imu, Range
from sitl.vehicle.world import start_on_ground, world_beam

NO_RETURN_M = 999.0  # beam pointing away from the ground: beyond any rangefinder's maximum
#: what ArduPilot's SITL rangefinder reads as "no data": only a NaN or an infinity
#: (libraries/AP_RangeFinder/AP_RangeFinder_SITL.cpp); a negative distance reads as 0 m, "too close"
NO_DATA_M = math.nan
#: how far (m, and rad of pitch) the body may move before the beam is traced again: a body at
#: rest moves by 1e-14 m a frame, and ArduPilot reads the range in centimetres at 20 Hz, while
#: the trace is a third of a frame's work at 800 frames a second (ArduCopter's boot on its pad)
BEAM_REUSE = 1e-6


class JsonPhysics:
    """One vehicle, stepped frame by frame; ``reset`` puts it back where it booted."""

    def __init__(
        self, scenario: Scenario, legs: LegsLink | None = None, events: Callable | None = None
    ) -> None:
        self.scn = scenario
        self.legs = legs
        self._send_event = events
        self.reset()

    def reset(self) -> None:
        self.rng = np.random.default_rng(self.scn.seed)
        self.stepper, self.world = start_on_ground(self.scn)
        b = self.stepper.body()
        self.home = self.world.to_world(b.x, b.z)
        self.t0 = self.stepper.t
        self.imu = Imu(self.rng, self.scn.accel_noise, self.scn.gyro_noise)
        self.range = Range(0.0, 1, 0)
        self._body = self.stepper.body()
        self._beam: tuple[float, float, float, float, float, bool, float] | None = None
        self.events = Events(self._send_event) if self._send_event is not None else None
        if self.legs is not None:
            self.legs.next_t = 0.0

    @property
    def t(self) -> float:
        """Physics time since boot or the last reset (s): the reply's timestamp."""
        return self.stepper.t - self.t0

    def statustext(self, text: str, severity: int = 6) -> None:
        """Where the leg link reports trouble: ArduPilot has no channel for it, so stderr."""
        print(f"json_physics: {text}", file=sys.stderr, flush=True)

    def step(self, dt: float, pwm: Sequence[int]) -> None:
        """Advance by one frame with the motor outputs (channels 1-4, microseconds)."""
        if self.events is not None:  # the outputs ArduCopter sent for this frame, at its start
            self.events.after_outputs(self.t, True, pwm)
        u_left, u_right = esc.planar_rotor_commands(pwm)
        if not self.scn.wind.calm:
            self.stepper.set_external_force(*self.scn.wind.force_at(self.t))
        self.stepper.step(dt, u_left, u_right)
        self.world.update(self.stepper)  # the surface under the position this frame reports
        self._body = b = self.stepper.body()
        fx, fz = self.stepper.specific_force_body()
        self.imu.accel_noise = self.scn.accel_noise + self.scn.imu_extra_noise(self.t)
        # ArduPilot filters the IMU itself (INS_*_FILTER): hand it the unfiltered reading
        self.imu.update(dt, fx, fz, b.pitch_rate, 0.0, 0.0, self.scn.imu_spike(self.t))
        true = self._trace_beam(b)  # NaN: the footprint straddles an edge
        status = 1 if math.isnan(true) else 4 if math.isfinite(true) else 3
        raw = Range(0.0, 1, 0) if status == 1 else Range(true, status, 100)
        self.range = self.scn.range_fault(self.t, raw, self.rng)
        if self.legs is not None:
            self.legs.update(self)
        if self.events is not None:
            self.events.after_physics_step(self.stepper, self.t, lambda: self._world_body(b))

    def height_m(self) -> float:
        """Height (m) of the body over the surface under it, this frame."""
        x, z = self.world.to_world(self._body.x, self._body.z)
        return z - self.world.surface_z(x)

    def _world_body(self, b):
        """Body ``b`` in world coordinates."""
        x, z = self.world.to_world(b.x, b.z)
        return replace(b, x=x, z=z)

    def _trace_beam(self, b) -> float:
        """:func:`world_beam` for body ``b``, traced again only once the body or the world under
        it has moved (:data:`BEAM_REUSE`)."""
        w, last = self.world, self._beam
        if (
            last is not None
            and abs(b.x - last[0]) < BEAM_REUSE
            and abs(b.z - last[1]) < BEAM_REUSE
            and abs(b.pitch - last[2]) < BEAM_REUSE
            and (w.ox, w.oz, w.on_roof) == last[3:6]
        ):
            return last[6]
        value = world_beam(self.stepper, w)
        self._beam = (b.x, b.z, b.pitch, w.ox, w.oz, w.on_roof, value)
        return value

    def fdm(self) -> Fdm:
        b = self._body
        x, z = self.world.to_world(b.x, b.z)
        if self.range.status == 1:
            rng = NO_DATA_M
        elif not math.isfinite(self.range.distance_m):
            rng = NO_RETURN_M
        else:
            rng = max(0.0, self.range.distance_m)
        a, g = self.imu.accel, self.imu.gyro
        return Fdm(
            timestamp=self.t,
            gyro=(float(g[0]), float(g[1]), float(g[2])),
            accel_body=(float(a[0]), float(a[1]), float(a[2])),
            position=(x - self.home[0], 0.0, -(z - self.home[1])),
            velocity=(b.vx, 0.0, -b.vz),
            attitude=(0.0, b.pitch, 0.0),
            rng_1=rng,
        )
