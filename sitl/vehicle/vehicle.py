"""The simulated ArduCopter: physics at 1200 Hz, control and the on-board script at 400 Hz,
MAVLink in and out every control tick, all on the vehicle's own simulated clock."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from sitl.vehicle import esc, landing_record, modes
from sitl.vehicle.events import Events
from sitl.vehicle.flight_control import FlightControl, Target
from sitl.vehicle.land_detector import LandDetector
from sitl.vehicle.mavlink_endpoints import Endpoints, mavlink
from sitl.vehicle.params import Params
from sitl.vehicle.scenario import Scenario
from sitl.vehicle.sensors import Imu, Range, range_reading
from sitl.vehicle.streams import Streams, system_time
from sitl.vehicle.world import beam_range, start_on_ground
from slopelander.model.judge import LandingJudge

PHYSICS_HZ = 1200
CONTROL_HZ = 400
SUBSTEPS = PHYSICS_HZ // CONTROL_HZ
FORCE_MAGIC = 21196
LOCKSTEP_LEAD_S = 0.05
LOCKSTEP_GIVE_UP_S = 1.0  # wall seconds without a new echo before the vehicle stops waiting


class Vehicle:
    def __init__(
        self,
        links: Endpoints,
        params: Params,
        scenario: Scenario,
        script: Path | None = None,
        speed: float = 1.0,
        lockstep: bool = False,
        legs_link=None,
    ) -> None:
        self.links, self.params, self.scn = links, params, scenario
        self.speed, self.lockstep, self.legs = speed, lockstep, legs_link
        self.rng = np.random.default_rng(scenario.seed)
        self.stepper, self.world = start_on_ground(scenario)
        self.judge = LandingJudge(self.stepper)  # each landing's record, as the model judges it
        b = self.stepper.body()
        self.home = self.world.to_world(b.x, b.z)  # world frame: it stays put when the surface switches
        p = self.stepper.model.params
        mass = p["body_mass"] + 2 * p["leg_mass"]
        self.fc = FlightControl(mass, p["body_inertia"], p["rotor_arm"], p["gravity"], p["rotor_thrust_max"])
        self.thrust_max = p["rotor_thrust_max"]
        self.t0 = self.stepper.t
        self.imu = Imu(self.rng, scenario.accel_noise, scenario.gyro_noise)
        self.range = Range(0.0, 1, 0)
        self.land = LandDetector()
        self.streams = Streams()
        self.armed = False
        self.estop = False
        self.mode = modes.STABILIZE
        self.target = Target()
        self.target_time = -1.0  # vehicle time of the last GUIDED velocity target
        self.target_is_velocity = False
        self.mixer_pwm = [int(params["MOT_PWM_MIN"])] * 4
        self.out_pwm = list(self.mixer_pwm)
        self.rc_override: dict[int, tuple[int, float]] = {}
        self.echo_t: float | None = None
        self.echo_wall = 0.0
        self.running = True
        self.events = Events(self._send_event)  # measurement hooks (docs/simulated-vehicle.md)
        self.host = None
        if script is not None:
            from sitl.vehicle.script_io import ScriptIO
            from sitl.vehicle.scripting import RangeReading, ScriptHost

            self.host = ScriptHost(script, ScriptIO(self, RangeReading))

    # -- clock ---------------------------------------------------------------------------------
    @property
    def t(self) -> float:
        """Vehicle time since boot (s)."""
        return self.stepper.t - self.t0

    @property
    def range_min(self) -> float:
        return self.params["RNGFND1_MIN"]

    @property
    def range_max(self) -> float:
        return self.params["RNGFND1_MAX"]

    def rc(self, chan: int) -> int:
        ov = self.rc_override.get(chan)
        if ov is not None and self.t - ov[1] < 3.0:
            return ov[0]
        return self.scn.rc_at(chan, self.t)

    # -- arming and modes ----------------------------------------------------------------------
    def prearm_failure(self) -> str | None:
        if self.estop:
            return "Motors Emergency Stopped"
        if self.mode not in modes.ARMABLE:
            return f"Mode not armable ({modes.NAMES[self.mode]})"
        if self.params["ARMING_CHECK"] != 0:
            lean = abs(math.degrees(self.stepper.body().pitch))
            if lean * 100 > self.params["ANGLE_MAX"]:
                return f"Leaning ({lean:.0f} deg > ANGLE_MAX {self.params['ANGLE_MAX'] / 100:.0f})"
            if self.mode in (modes.STABILIZE, modes.ALT_HOLD) and self.rc(3) > 1100:
                return "Throttle too high"
        return None

    def arm(self, force: bool, source: str = "GCS") -> bool:
        if self.armed:
            return True
        why = None if force else self.prearm_failure()
        if why:
            self.statustext(f"PreArm: {why}", mavlink.MAV_SEVERITY_CRITICAL)
            return False
        self.armed = True
        self.fc.reset()
        self.land.landed = True
        self.statustext(f"Arming motors ({source})", mavlink.MAV_SEVERITY_INFO)
        return True

    def disarm(self, source: str = "GCS") -> bool:
        if self.armed:
            self.armed = False
            self.statustext(f"Disarming motors ({source})", mavlink.MAV_SEVERITY_INFO)
        return True

    def set_mode(self, mode: int, source: str = "GCS") -> bool:
        if mode not in modes.NAMES:
            return False
        b = self._world_body()  # targets are world coordinates (over the roof the model frame is shifted)
        self.mode = mode
        self.target = Target(x=b.x, z=b.z) if not self.land.landed else Target(x=b.x, vz=-0.5)
        self.target_is_velocity = False
        if mode == modes.LAND:
            self.target = Target(x=b.x)
        self.fc.ix = 0.0
        return True

    # -- messages out --------------------------------------------------------------------------
    def statustext(self, text: str, severity: int = 6) -> None:
        self.links.send(mavlink.MAVLink_statustext_message(severity, text[:50].encode(), 0, 0))

    def send_named_float(self, name: str, value: float) -> None:
        self.links.send(
            mavlink.MAVLink_named_value_float_message(int(self.t * 1000), name[:10].encode(), float(value))
        )

    def _send_event(self, name: str, t: float, value: float) -> None:
        self.links.send(mavlink.MAVLink_named_value_float_message(int(t * 1000), name.encode(), float(value)))

    def ack(self, command: int, result: int, progress: int = 0) -> None:
        self.links.send(mavlink.MAVLink_command_ack_message(command, result, progress, 0, 0, 0))

    # -- one control tick ----------------------------------------------------------------------
    def tick(self) -> None:
        dt = 1.0 / CONTROL_HZ
        self.scn.apply_events(self)
        for chan, m in self.links.receive():
            self.handle(chan, m)
        if self.world.update(self.stepper):
            self.fc.ix = 0.0
        b = self._world_body()
        tgt = self._mode_target(b)
        front, rear = self.fc.update(dt, b, tgt, math.radians(self.params["ANGLE_MAX"] / 100))
        self.mixer_pwm = self._mix(front, rear)
        now_ms = int(self.t * 1000)
        if self.host is not None and not self.scn.script_stalled(self.t):
            self.host.run_due(now_ms)
        out = list(self.mixer_pwm)
        if self.host is not None and self.armed:
            for ch in range(4):
                o = self.host.output_override(ch, now_ms)
                if o is not None:
                    out[ch] = int(o)
        self.out_pwm = out
        self.events.after_outputs(self.t, self.armed, out)
        u_rear, u_front = esc.planar_rotor_commands(out)
        self.imu.accel_noise = self.scn.accel_noise + self.scn.imu_extra_noise(self.t)
        ca, cg = self.params["INS_ACCEL_FILTER"], self.params["INS_GYRO_FILTER"]
        wind = None if self.scn.wind.calm else self.scn.wind
        for _ in range(SUBSTEPS):
            if wind is not None:
                self.stepper.set_external_force(*wind.force_at(self.t))
            self.stepper.step(1.0 / PHYSICS_HZ, u_rear, u_front)
            if self.judge.update(1.0 / PHYSICS_HZ, u_rear, u_front):
                landing_record.send(self, self.judge)
            fx, fz = self.stepper.specific_force_body()
            self.imu.update(
                1.0 / PHYSICS_HZ, fx, fz, self.stepper.body().pitch_rate, ca, cg, self.scn.imu_spike(self.t)
            )
            self.events.after_physics_step(self.stepper, self.t, self._world_body())
        self._update_range()
        b = self._world_body()
        acc = self.stepper._accel
        floor = self.fc.throttle <= self._spin_min_throttle() + 0.02
        self.land.update(dt, self.armed, floor, (float(acc[0]), float(acc[1])), b.vz)
        if self.armed and self.mode == modes.LAND and self.land.landed and self._landing:
            self.disarm("Land")
        if self.legs is not None:
            self.legs.update(self)
        self.streams.send_due(self)

    @property
    def _landing(self) -> bool:
        return self.fc.throttle <= self._spin_min_throttle() + 0.02

    def _spin_min_throttle(self) -> float:
        return 0.0

    def _world_body(self):
        b = self.stepper.body()
        x, z = self.world.to_world(b.x, b.z)
        return b.__class__(b.t, x, z, b.pitch, b.vx, b.vz, b.pitch_rate)

    def _mode_target(self, b) -> Target:
        t, m = self.target, self.mode
        if m == modes.STABILIZE:
            thr = min(1.0, max(0.0, (self.rc(3) - 1000) / 1000.0))
            return Target(
                pitch=(self.rc(2) - 1500) / 500.0 * math.radians(self.params["ANGLE_MAX"] / 100),
                throttle=thr * 0.9,
            )
        if m in (modes.ALT_HOLD, modes.LOITER):
            vz = _stick(self.rc(3)) * self.params["PILOT_SPEED_UP"] / 100.0
            if abs(vz) > 0.01 or t.z is None:
                t = Target(x=t.x, z=b.z if abs(vz) < 0.01 else None, vx=t.vx, vz=vz)
                self.target = t
            if m == modes.LOITER:
                vx = -_stick(self.rc(2)) * 5.0
                if abs(vx) > 0.01:
                    self.target = t = Target(x=None, z=t.z, vx=vx, vz=t.vz)
                elif t.x is None:
                    self.target = t = Target(x=b.x, z=t.z, vz=t.vz)
            return t
        if m == modes.GUIDED:
            if self.target_is_velocity and self.t - self.target_time > self.params["GUID_TIMEOUT"]:
                self.target_is_velocity = False
                self.target = t = Target(x=b.x, z=b.z)  # stale target: stop and hold
            return t
        if m == modes.BRAKE:
            if t.x is None or t.z is None:
                self.target = t = Target(x=b.x, z=b.z)
            return t
        if m == modes.RTL:
            hx, hz = self.home
            alt = max(self.params["RTL_ALT"] / 100.0, 0.0)
            if abs(b.x - hx) > 0.3:
                return Target(x=hx, z=max(b.z, hz + alt))
            return Target(x=hx, vz=-self.params["LAND_SPEED"] / 100.0)
        if m == modes.LAND:
            return Target(x=t.x, vz=-self.params["LAND_SPEED"] / 100.0)
        return t

    def _mix(self, front_n: float, rear_n: float) -> list[int]:
        lo, hi = self.params["MOT_PWM_MIN"], self.params["MOT_PWM_MAX"]
        if not self.armed or self.estop:
            return [int(lo)] * 4
        spin_arm = lo + self.params["MOT_SPIN_ARM"] * (hi - lo)
        spin_min = lo + self.params["MOT_SPIN_MIN"] * (hi - lo)
        if self.land.landed and self.fc.throttle < 0.5 and self.mode != modes.STABILIZE:
            # spooled down on the ground until the mode asks to climb
            wants_up = (
                self.target.z is not None and self.target.z > self._world_body().z + 0.05
            ) or self.target.vz > 0.05
            if not wants_up:
                self.fc.settle_on_ground()
                return [int(spin_arm)] * 4

        def pwm(f: float) -> int:
            u = math.sqrt(max(0.0, f) / self.thrust_max)
            return round(min(hi, max(spin_min, esc.command_to_pwm(u))))

        pf, pr = pwm(front_n), pwm(rear_n)
        return [pf, pr, pf, pr]

    def _update_range(self) -> None:
        true = beam_range(self.stepper)
        r = range_reading(true, self.range_min, self.range_max)
        self.range = self.scn.range_fault(self.t, r, self.rng)

    # -- MAVLink in ----------------------------------------------------------------------------
    def handle(self, chan: int, m) -> None:
        from sitl.vehicle import commands

        commands.handle(self, chan, m)

    # -- main loop -----------------------------------------------------------------------------
    def run(self) -> None:
        wall0, sim0 = time.monotonic(), self.t
        while self.running:
            self.tick()
            if self.lockstep:
                self._wait_for_companion()
            if self.speed > 0:
                ahead = (self.t - sim0) / self.speed - (time.monotonic() - wall0)
                if ahead > 0.002:
                    time.sleep(ahead)
                elif ahead < -0.5:  # fell far behind (CPU load): do not try to catch up in a burst
                    wall0 = time.monotonic() - (self.t - sim0) / self.speed

    def _wait_for_companion(self) -> None:
        if self.running and self.echo_t is not None and self.t - self.echo_t > LOCKSTEP_LEAD_S:
            # tell the companion the time it waits at: with no fast stream asked for yet, nothing
            # else it reads may carry a newer stamp, and both would wait for the give-up
            self.links.send(system_time(self))
        while self.running and self.echo_t is not None and self.t - self.echo_t > LOCKSTEP_LEAD_S:
            if time.monotonic() - self.echo_wall > LOCKSTEP_GIVE_UP_S:
                self.echo_t = None  # the companion went away: run free until it echoes again
                return
            got = self.links.receive()
            for chan, m in got:
                self.handle(chan, m)
            if not got:
                time.sleep(0.0005)


def _stick(pwm: int, dead: int = 50) -> float:
    """Centred stick in -1..1 with ArduPilot's deadzone."""
    d = pwm - 1500
    if abs(d) <= dead:
        return 0.0
    return max(-1.0, min(1.0, (d - math.copysign(dead, d)) / (500 - dead)))
