"""The simulated ArduCopter: physics at 1200 Hz, control and the on-board script at 400 Hz,
MAVLink in and out every control tick, all on the vehicle's own simulated clock."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from slopelander.model.judge import LandingJudge
from slopelander.model.stepper import BodyState
from slopelander_sitl.vehicle import arducopter_rules as rules
from slopelander_sitl.vehicle import esc, landing_record, modes
from slopelander_sitl.vehicle.events import Events
from slopelander_sitl.vehicle.flight_control import FlightControl, Target
from slopelander_sitl.vehicle.mavlink_endpoints import Endpoints, mavlink
from slopelander_sitl.vehicle.params import Params
from slopelander_sitl.vehicle.scenario import Scenario
from slopelander_sitl.vehicle.sensors import BEAM_MISS_M, Imu, NormalStream, Range, range_reading
from slopelander_sitl.vehicle.streams import Streams, system_time
from slopelander_sitl.vehicle.world import start_on_ground, world_beam

PHYSICS_HZ = 1200
CONTROL_HZ = 400
SUBSTEPS = PHYSICS_HZ // CONTROL_HZ
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
        give_up_s: float = LOCKSTEP_GIVE_UP_S,
    ) -> None:
        self.links, self.params, self.scn = links, params, scenario
        self.speed, self.lockstep, self.legs = speed, lockstep, legs_link
        self.give_up_s = give_up_s
        self.rng = np.random.default_rng(scenario.seed)
        # the IMU and the range noise draw from one stream, in the order they did from the
        # Generator (sensors.NormalStream): the same numbers, a block at a time
        self.normals = NormalStream(self.rng)
        self.stepper, self.world = start_on_ground(scenario)
        self.judge = LandingJudge(self.stepper)  # each landing's record, as the model judges it
        b = self.stepper.body()
        # the EKF origin, where the vehicle started: LOCAL_POSITION_NED and local targets count from it
        self.home = self.world.to_world(b.x, b.z)  # world frame: it stays put when the surface switches
        self.home_ne = self.world.ne(self.home[0])  # (north, east): it stays put when the vehicle turns
        # ArduCopter's home, which the take-off's "above home" and RTL count from: where the vehicle
        # last armed (AP_Arming_Copter::arm, ArduCopter/AP_Arming_Copter.cpp: home reset to the
        # current location at each arming unless locked); the origin does not move with it
        self.arm_home, self.arm_home_ne = self.home, self.home_ne
        p = self.stepper.model.params
        mass = p["body_mass"] + 2 * p["leg_mass"]
        self.fc = FlightControl(mass, p["body_inertia"], p["rotor_arm"], p["gravity"], p["rotor_thrust_max"])
        self.thrust_max = p["rotor_thrust_max"]
        self.t0 = self.stepper.t
        self.imu = Imu(self.normals, scenario.accel_noise, scenario.gyro_noise)
        self.range = Range(0.0, 1, 0)
        self.range_alt = rules.RangefinderAlt()
        self.ticks = 0
        self.land = rules.LandDetector(CONTROL_HZ)
        self.streams = Streams(len(links.conns))
        self.armed = False
        self.estop = False
        self.mode = modes.STABILIZE
        self.target = Target()
        self.target_time = -1.0  # vehicle time of the last GUIDED velocity target
        self.target_is_velocity = False
        #: the heading GUIDED turns to (deg from north), None: hold the heading there is
        self.heading_target: float | None = None
        self.yaw_rate = 0.0  # rad/s, the last tick's turn
        #: a GUIDED position target and the point on the earth (north, east) it was asked for
        self.target_ne: tuple[Target, float, float] | None = None
        self.mixer_pwm = [int(params["MOT_PWM_MIN"])] * 4
        self.out_pwm = list(self.mixer_pwm)
        self._rotors: tuple | None = None  # the last outputs and their rotor commands
        self.rc_override: dict[int, tuple[int, float]] = {}
        self.echo_t: float | None = None
        self.echo_wall = 0.0
        self.running = True
        self.events = Events(self._send_event)  # measurement hooks (docs/simulated-vehicle.md)
        self.host = None
        if script is not None:
            from slopelander_sitl.vehicle.script_io import ScriptIO
            from slopelander_sitl.vehicle.scripting import RangeReading, ScriptHost

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
    def arming_failure(self, source: str = rules.GCS) -> str | None:
        """Why an arming attempt with checks fails now (arducopter_rules.arming_failure)."""
        return rules.arming_failure(
            self.mode,
            source,
            self.estop,
            abs(self.stepper.body().pitch),  # planar: roll 0, so acos(cos roll cos pitch) = |pitch|
            self.params["ANGLE_MAX"],
            self.params["ARMING_CHECK"],
            pilot_climb=self.mode in (modes.ALT_HOLD, modes.LOITER) and _stick(self.rc(3)) > 0,
            throttle_stick_up=self.rc(3) > 1000 + 30,
            rc_options=int(self.params["RC_OPTIONS"]),
        )

    def arm(self, force: bool, source: str = rules.GCS) -> bool:
        """Arm; ``force`` skips the checks (ARM_DISARM param2 2989). False with a STATUSTEXT
        "Arm: <reason>" when a check fails."""
        if self.armed:
            return True
        why = None if force else self.arming_failure(source)
        if why:
            self.statustext(why, mavlink.MAV_SEVERITY_CRITICAL)
            return False
        self.armed = True
        b = self._world_body()
        self.arm_home, self.arm_home_ne = (b.x, b.z), self.world.ne(b.x)
        self.fc.reset()
        self.land.set_landed(True)
        self.statustext("Arming motors", mavlink.MAV_SEVERITY_INFO)
        return True

    def disarm(self, source: str = rules.GCS, checks: bool = True) -> bool:
        """Disarm, unless ArduCopter would refuse it (a ground-station disarm before the land
        detector has fired; arducopter_rules.disarm_refused). The script's disarm is never refused."""
        if not self.armed:
            return True
        if rules.disarm_refused(source, checks, self.land.landed, self.mode in modes.MANUAL_THROTTLE):
            return False
        self.armed = False
        self.land.set_landed(True)
        self.statustext("Disarming motors", mavlink.MAV_SEVERITY_INFO)
        return True

    def takeoff(self, height_m: float, param3: float = 0.0) -> bool:
        """MAV_CMD_NAV_TAKEOFF as ArduCopter takes it (arducopter_rules.takeoff); False: refused."""
        b = self._world_body()
        above_home = b.z - self.arm_home[1]
        ok = self.range_alt.healthy
        t = rules.takeoff(
            self.mode,
            self.armed,
            self.land.landed,
            height_m,
            param3,
            above_home,
            ok,
            self.range_alt.alt_m,
            self.range_max,
            self.params["WPNAV_RFND_USE"],
        )
        if t is None:
            return False
        z = (b.z - self.range_alt.alt_m + t.height_m) if t.above_terrain else self.arm_home[1] + t.height_m
        self.target = Target(x=b.x, z=z)
        self.target_is_velocity = False
        self.heading_target = None
        self.land.set_landed(False)
        self.fc.ix = 0.0
        return True

    def set_mode(self, mode: int, source: str = rules.GCS) -> bool:
        if mode not in modes.NAMES:
            return False
        b = self._world_body()  # targets are world coordinates (over the roof the model frame is shifted)
        self.mode = mode
        self.target = Target(x=b.x, z=b.z) if not self.land.landed else Target(x=b.x, vz=-0.5)
        self.target_is_velocity = False
        self.heading_target = None
        if mode == modes.LAND:
            self.target = Target(x=b.x)
        self.fc.ix = 0.0
        return True

    # -- messages out --------------------------------------------------------------------------
    def statustext(self, text: str, severity: int = 6) -> None:
        """A STATUSTEXT; a text over 50 characters goes in numbered chunks (GCS::send_textv)."""
        raw = text.encode()
        if len(raw) <= 50:
            self.links.send(mavlink.MAVLink_statustext_message(severity, raw, 0, 0))
            return
        self._text_id = getattr(self, "_text_id", 0) % 65535 + 1
        for seq, i in enumerate(range(0, len(raw), 50)):
            self.links.send(mavlink.MAVLink_statustext_message(severity, raw[i : i + 50], self._text_id, seq))

    def send_named_float(self, name: str, value: float) -> None:
        self.links.send(
            mavlink.MAVLink_named_value_float_message(int(self.t * 1000), name[:10].encode(), float(value))
        )

    def _send_event(self, name: str, t: float, value: float) -> None:
        self.links.send(mavlink.MAVLink_named_value_float_message(int(t * 1000), name.encode(), float(value)))

    def ack(self, command: int, result: int, progress: int = 0, chan: int | None = None) -> None:
        """COMMAND_ACK on the link the command came from (``chan``), as ArduCopter answers on the
        channel that asked; None: every link."""
        self.links.send(mavlink.MAVLink_command_ack_message(command, result, progress, 0, 0, 0), chan)

    # -- one control tick ----------------------------------------------------------------------
    def tick(self) -> None:
        """One control tick and its physics steps. The vehicle time is read once per physics
        step (nothing else moves it within a tick) and the rotor commands are mapped again only
        when the outputs change: 400 ticks a simulated second."""
        dt = 1.0 / CONTROL_HZ
        scn, st, t0 = self.scn, self.stepper, self.t0
        scn.apply_events(self)
        for chan, m in self.links.receive():
            self.handle(chan, m)
        if self.world.update(st):
            self.fc.ix = 0.0
        self._turn(dt)
        b = self._world_body()
        tgt = self._mode_target(b)
        front, rear = self.fc.update(dt, b, tgt, math.radians(self.params["ANGLE_MAX"] / 100))
        if self.armed and self.land.landed and self._pilot_takes_off():
            self.land.set_landed(False)
        self.mixer_pwm = self._mix(front, rear)
        t = st.t - t0
        now_ms = int(t * 1000)
        if self.host is not None and not scn.script_stalled(t):
            self.host.run_due(now_ms)
            if not self.armed:  # the script disarmed: this tick's outputs are the disarmed ones
                self.mixer_pwm = self._mix(front, rear)
        out = list(self.mixer_pwm)
        if self.host is not None and self.armed:
            for ch in range(4):
                o = self.host.output_override(ch, now_ms)
                if o is not None:
                    out[ch] = int(o)
        self.out_pwm = out
        self.events.after_outputs(t, self.armed, out)
        rotors = self._rotors
        if rotors is None or rotors[0] != out:
            self._rotors = rotors = (list(out), esc.planar_rotor_commands(out))
        u_rear, u_front = rotors[1]
        imu, events, judge = self.imu, self.events, self.judge
        imu.accel_noise = scn.accel_noise + scn.imu_extra_noise(t)
        ca, cg = self.params["INS_ACCEL_FILTER"], self.params["INS_GYRO_FILTER"]
        wind = None if scn.wind.calm else scn.wind
        h = 1.0 / PHYSICS_HZ
        turn_rate = self.yaw_rate
        roll_rate = yaw_rate = 0.0
        for _ in range(SUBSTEPS):
            if wind is not None:
                st.set_external_force(*wind.force_at(t))
            st.step(h, u_rear, u_front)
            if judge.update(h, u_rear, u_front):
                landing_record.send(self, judge)
            fx, fz = st.specific_force_body()
            t = st.t - t0
            if turn_rate:
                pitch = st.motion()[3]
                roll_rate, yaw_rate = -turn_rate * math.sin(pitch), turn_rate * math.cos(pitch)
            imu.update(h, fx, fz, st.pitch_rate, ca, cg, scn.imu_spike(t), roll_rate, yaw_rate)
            events.after_physics_step(st, t, self._world_body)
        if rules.rangefinder_due(self.ticks, CONTROL_HZ):
            self._update_range()
        self.ticks += 1
        b = self._world_body()
        self._update_land_detector(dt, b)
        if self.armed and self.land.landed and rules.mode_disarms_on_land(self.mode):
            self.disarm(rules.LANDED)
        if self.legs is not None:
            self.legs.update(self)
        self.streams.send_due(self)

    def _update_land_detector(self, dt: float, b) -> None:
        acc = self.stepper._accel
        pitch_err = math.degrees(abs(self.fc.pitch_target - b.pitch))
        self.land.update(
            dt,
            rules.LandInputs(
                armed=self.armed,
                throttle_at_lower_limit=self.fc.demand <= self._spin_min_throttle(),
                angle_target_deg=math.degrees(abs(self.fc.pitch_target)),
                angle_error_deg=pitch_err,
                accel_ef=(float(acc[0]), float(acc[1])),
                climb_rate=b.vz,
                descent_demanded=self.fc.vz_desired < 0.0,
                landing_mode=self.mode in (modes.LAND, modes.RTL),
                rangefinder_alt_ok=self.range_alt.healthy,
                rangefinder_alt_filt_m=self.range_alt.alt_filt_m,
            ),
        )

    def _spin_min_throttle(self) -> float:
        """Collective (fraction of full thrust) at MOT_SPIN_MIN: the mixer's floor in flight;
        a demand at or below it is AP_Motors' limit.throttle_lower."""
        lo, hi = self.params["MOT_PWM_MIN"], self.params["MOT_PWM_MAX"]
        u = esc.pwm_to_command(lo + self.params["MOT_SPIN_MIN"] * (hi - lo))
        return u * u

    def _pilot_takes_off(self) -> bool:
        thr = min(1.0, max(0.0, (self.rc(3) - 1000) / 1000.0))
        return rules.pilot_takes_off(self.mode, _stick(self.rc(3)), thr * 0.9, 0.5)

    def _turn(self, dt: float) -> None:
        """Turn toward :attr:`heading_target` at up to ATC_SLEW_YAW (ArduCopter's default yaw
        slew, 60 deg/s), in the air only. The planar physics turns with the heading
        (:meth:`World.turn`); its position target goes to the nearest point of the new slice to the
        point on the earth it was asked for (a turn is flown at hover, over the target)."""
        self.yaw_rate = 0.0
        w = self.world
        if self.heading_target is None or not self.armed or self.land.landed:
            return
        err = (self.heading_target - w.heading_deg + 180.0) % 360.0 - 180.0
        if err == 0.0:
            return
        most = self.params["ATC_SLEW_YAW"] / 100.0 * dt
        step = err if abs(err) <= most else math.copysign(most, err)
        x_target = self.target.x
        ne_target = None if x_target is None else w.ne(x_target)
        if self.target_ne is not None and self.target_ne[0] is self.target:
            ne_target = self.target_ne[1:]  # the point asked for, not its projection on the old line
        if w.turn(self.stepper, self.heading_target if step == err else w.heading_deg + step):
            self.yaw_rate = math.radians(step) / dt
            if ne_target is not None:
                self.target.x = w.slice_x(*ne_target)

    def _world_body(self) -> BodyState:
        """The body in world coordinates (world.to_world), built once from the plain state."""
        t, x, z, pitch, vx, vz, pitch_rate = self.stepper.motion()
        w = self.world
        return BodyState(t, x + w.ox, z + w.oz, pitch, vx, vz, pitch_rate)

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
            if rules.guided_target_stale(
                self.target_is_velocity, self.t, self.target_time, self.params["GUID_TIMEOUT"]
            ):
                self.target_is_velocity = False
                if t.x is None or t.z is None:
                    self.target = t = Target(x=b.x, z=b.z)  # stale velocity target: stop and hold
                else:
                    self.target = t = Target(x=t.x, z=t.z)  # position kept, its velocity zeroed
            return t
        if m == modes.BRAKE:
            if t.x is None or t.z is None:
                self.target = t = Target(x=b.x, z=b.z)
            return t
        if m == modes.RTL:
            hx, hz = self.world.slice_x(*self.arm_home_ne), self.arm_home[1]
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
        spin_min = lo + self.params["MOT_SPIN_MIN"] * (hi - lo)
        manual_idle = self.mode in modes.MANUAL_THROTTLE and self.land.landed and self.rc(3) <= 1000 + 30
        if rules.ground_idle(self.armed, self.land.landed, self.mode, self.estop) or manual_idle:
            # armed on the ground: MOT_SPIN_ARM until the mode takes off (arducopter_rules (e))
            self.fc.settle_on_ground()
            return [rules.spin_arm_pwm(lo, hi, self.params["MOT_SPIN_ARM"])] * 4

        def pwm(f: float) -> int:
            u = math.sqrt(max(0.0, f) / self.thrust_max)
            return round(min(hi, max(spin_min, esc.command_to_pwm(u))))

        pf, pr = pwm(front_n), pwm(rear_n)
        return [pf, pr, pf, pr]

    def _update_range(self) -> None:
        """The 20 Hz rangefinder task (arducopter_rules (d)): the beam's distance read as
        ArduPilot's SITL driver reads a value, then the scenario's faults, then the height the
        land detector and take-off use."""
        true = world_beam(self.stepper, self.world)
        if math.isnan(true):  # the beam's footprint straddles an edge: no return
            raw = Range(0.0, rules.NO_DATA, 0)
        else:
            raw = Range(true if math.isfinite(true) else BEAM_MISS_M, 4, 100)
        # faults act on the value, then ArduPilot reads it
        r = self.scn.range_fault(self.t, raw, self.normals)
        value = math.nan if r.status == rules.NO_DATA else r.distance_m
        self.range = range_reading(value, self.range_min, self.range_max)
        lean = self.stepper.body().pitch
        self.range_alt.update(self.range.distance_m, self.range.status, lean, 1.0 / rules.RANGEFINDER_HZ)

    # -- MAVLink in ----------------------------------------------------------------------------
    def handle(self, chan: int, m) -> None:
        from slopelander_sitl.vehicle import commands

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
            if time.monotonic() - self.echo_wall > self.give_up_s:
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
