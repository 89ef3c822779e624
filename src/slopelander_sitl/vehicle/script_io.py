"""What the on-board script sees of the simulated vehicle: the ``VehicleIO`` the Lua host
(``slopelander_sitl.vehicle.scripting``) binds ArduPilot's scripting API to."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from slopelander_sitl.vehicle import modes
from slopelander_sitl.vehicle.flight_control import Target

if TYPE_CHECKING:
    from slopelander_sitl.vehicle.vehicle import Vehicle


#: ArduCopter reads its rangefinder at 20 Hz (``ArduCopter/Copter.cpp``, the scheduler's
#: ``read_rangefinder`` entry), not at the loop rate: the script sees a new sample, with a new
#: driver reading time (``RangeFinder_State.last_reading_ms``), every 50 ms
RANGEFINDER_PERIOD_MS = 50


class ScriptIO:
    def __init__(self, vehicle: Vehicle, range_cls: type) -> None:
        self.v = vehicle
        self._range_cls = range_cls
        self._sample = None  # the rangefinder sample the script sees, and its reading time (ms)
        self._sample_ms = -RANGEFINDER_PERIOD_MS

    def time_ms(self) -> int:
        return int(self.v.t * 1000)

    def time_us(self) -> int:
        return int(self.v.t * 1e6)

    def is_armed(self) -> bool:
        return self.v.armed

    def arm(self) -> bool:
        return self.v.arm(force=False, source="Script")

    def disarm(self) -> bool:
        return self.v.disarm(source="Script")

    def mode(self) -> int:
        return self.v.mode

    def set_mode(self, mode: int) -> bool:
        return self.v.set_mode(int(mode), source="Script")

    def set_target_velocity_ned(self, north: float, east: float, down: float) -> bool:
        """``vehicle:set_target_velocity_NED`` (Copter::set_target_velocity_NED): refused outside
        GUIDED; a velocity target, which lapses after GUID_TIMEOUT like the companion's
        (the planar vehicle flies north and up only: east is not flown)."""
        if self.v.mode != modes.GUIDED or not all(map(math.isfinite, (north, east, down))):
            return False
        self.v.target = Target(vx=north, vz=-down)
        self.v.target_is_velocity = True
        self.v.target_time = self.v.t
        return True

    def emergency_stop(self) -> bool:
        return self.v.estop

    def accel(self) -> tuple[float, float, float]:
        a = self.v.imu.accel
        return float(a[0]), float(a[1]), float(a[2])

    def gyro(self) -> tuple[float, float, float]:
        g = self.v.imu.gyro
        return float(g[0]), float(g[1]), float(g[2])

    def attitude(self) -> tuple[float, float, float]:
        """Roll, pitch, yaw (rad) as ``ahrs:get_roll()`` ... read them (the planar model pitches only)."""
        heading = (self.v.world.heading_deg + 180.0) % 360.0 - 180.0
        return 0.0, float(self.v.stepper.body().pitch), math.radians(heading)

    def velocity_ned(self) -> tuple[float, float, float] | None:
        """The velocity ``ahrs:get_velocity_NED()`` returns (m/s, north-east-down), as the
        LOCAL_POSITION_NED stream sends it."""
        b = self.v._world_body()
        c, s = self.v.world._dir()
        return float(b.vx * c), float(b.vx * s), float(-b.vz)

    def rangefinder(self, orientation: int):  # -> RangeReading | None
        """The newest 20 Hz sample (:data:`RANGEFINDER_PERIOD_MS`), held between samples."""
        if orientation != int(self.v.params["RNGFND1_ORIENT"]):
            return None
        now = self.time_ms()
        if self._sample is None or now - self._sample_ms >= RANGEFINDER_PERIOD_MS or now < self._sample_ms:
            r = self.v.range
            self._sample_ms = now - now % RANGEFINDER_PERIOD_MS
            self._sample = self._range_cls(
                distance_m=r.distance_m if math.isfinite(r.distance_m) else self.v.range_max,
                status=r.status,
                signal_quality_pct=r.quality_pct,
                min_m=self.v.range_min,
                max_m=self.v.range_max,
                last_reading_ms=self._sample_ms,
            )
        return self._sample

    def rc_pwm(self, chan: int) -> int | None:
        return self.v.rc(chan) if 1 <= chan <= 16 else None

    def param(self, name: str) -> float | None:
        return self.v.params.get(name)

    def set_param(self, name: str, value: float) -> bool:
        return self.v.params.set(name, value)

    def send_text(self, severity: int, text: str) -> None:
        self.v.statustext(text, severity)

    def send_named_float(self, name: str, value: float) -> None:
        self.v.send_named_float(name, value)

    def send_mavlink(self, chan: int, msgid: int, payload: bytes) -> bool:
        return self.v.links.send_payload(chan, msgid, payload)

    def mixer_pwm(self, chan0: int) -> int:
        return self.v.mixer_pwm[chan0] if 0 <= chan0 < len(self.v.mixer_pwm) else 0
