"""slopelander's vehicle physics as ArduPilot's JSON interface sees it: four motor outputs in,
one frame's sensors out.

The same parts as the simulated vehicle (``slopelander_sitl.vehicle``): the model's Stepper on the
scenario's pad, roof and wind, the route-A ESC mapping (1500 us stopped, reversible, the model's
rotors holding the reversal delay), the IMU and rangefinder geometry, the scenario's sensor
faults and, when connected, the simulated leg board's torques. The planar model flies in the
vertical plane along the vehicle's heading (``slopelander_sitl.vehicle.world``): model x is the heading, model
z is up, model pitch is ArduPilot's pitch. Outside the model, in the air: the heading turns with
the motors' yaw torque (:class:`Yaw`) and the body rolls with their roll torque and slides
sideways under its tilted thrust (:class:`Roll`): ArduCopter's yaw and roll control drive them, as
they drive a real quad's, so it can turn the vehicle and hold it over a spot whatever its heading
(without the roll, a position error across the heading grew ArduCopter's integrators until a
turn flung the vehicle 2 m off). At heading 0 with no roll (every vehicle until something turns
or rolls it) model x is north and east stays zero.
Positions are from where the vehicle boots (ArduPilot's home).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from slopelander.model.stepper import BodyState, Stepper
from slopelander_sitl.json_physics.companion_gate import script_may_time
from slopelander_sitl.json_physics.protocol import Fdm, encode_full_reply, encode_planar_reply, encode_reply
from slopelander_sitl.vehicle import esc
from slopelander_sitl.vehicle.events import Events
from slopelander_sitl.vehicle.legs_link import LegsLink
from slopelander_sitl.vehicle.scenario import Scenario
from slopelander_sitl.vehicle.sensors import Imu, NormalStream, Range
from slopelander_sitl.vehicle.world import CLEAR_M, World, start_on_ground, world_beam

NO_RETURN_M = 999.0  # beam pointing away from the ground: beyond any rangefinder's maximum
#: what ArduPilot's SITL rangefinder reads as "no data": only a NaN or an infinity
#: (libraries/AP_RangeFinder/AP_RangeFinder_SITL.cpp); a negative distance reads as 0 m, "too close"
NO_DATA_M = math.nan
#: ArduPilot's quad X: motors 1 and 2 spin counter-clockwise (seen from above), 3 and 4 clockwise;
#: a motor's drag torque turns the body the other way, so more thrust on 1 and 2 turns it clockwise
#: (AP_MotorsMatrix: AP_MOTORS_MATRIX_YAW_FACTOR_CCW = +1 for motors 1 and 2)
YAW_SIGNS = (1.0, 1.0, -1.0, -1.0)
#: the body's yaw inertia (kg m^2) as a multiple of the model's pitch inertia, and a rotor's drag
#: torque per newton of its thrust (m): assumed, not measured. Only their ratio matters to the
#: turn, and it is set so that ArduCopter's default yaw gains turn the vehicle 90 deg with about
#: 10 deg of overshoot, within 1 deg after 3.5 s (2026-11-27, real ArduCopter SITL); a flat quad's
#: yaw inertia (twice the pitch's) with 9-inch props' 0.016 m overshot by 31 deg and wobbled +-5
#: deg: a real quad also turns by its rotors' reaction torque as they speed up, not modelled
YAW_INERTIA_PER_PITCH = 1.0
YAW_TORQUE_PER_THRUST_M = 0.03
#: ArduPilot's quad X: motors 1 (front right) and 4 (back right) on the right, 2 and 3 on the
#: left; more thrust on the left rolls the body right (positive roll)
ROLL_SIGNS = (-1.0, 1.0, 1.0, -1.0)
#: the body is moved to a new slice through it once it has slid this far across the old one (m)
SLIDE_STEP_M = 0.01
#: the heading is handed to the physics' plane (a new slice) once it has moved this far (deg):
#: each new slice costs a beam trace, and ArduCopter's yaw control moves the heading a little
#: every frame at hover
SLICE_STEP_DEG = 0.05
#: how far (m, and rad of pitch) the body may move before the beam is traced again: a body at
#: rest moves by 1e-14 m a frame, and ArduPilot reads the range in centimetres at 20 Hz, while
#: the trace is a third of a frame's work at 800 frames a second (ArduCopter's boot on its pad)
BEAM_REUSE = 1e-6
#: physics seconds between two ``TR_H`` events: the body's true height over the surface under it
#: (m), for a soak's checks on real ArduCopter, whose LOCAL_POSITION_NED is its EKF's estimate
TRUTH_PERIOD_S = 0.05


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
        # the IMU and the range noise draw from one stream, in the order they did from the
        # Generator (sensors.NormalStream): the same numbers, a block at a time
        self.normals = NormalStream(self.rng)
        self.stepper, self.world = start_on_ground(self.scn)
        b = self.stepper.body()
        self.home = self.world.to_world(b.x, b.z)
        self.t0 = self.stepper.t
        self.imu = Imu(self.normals, self.scn.accel_noise, self.scn.gyro_noise)
        self.range = Range(0.0, 1, 0)
        self._motion = self.stepper.motion()  # the body this frame reports, as a plain tuple
        self._beam: tuple | None = None
        self._outputs: tuple | None = None  # the last frame's motor outputs and their commands
        self.events = Events(self._send_event) if self._send_event is not None else None
        self._truth_next = 0.0
        self.home_ne = self.world.ne(self.home[0])
        self.roll = Roll(self.stepper.model.params)
        self.yaw = Yaw(self.stepper.model.params, self.roll)
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
        """Advance by one frame with the motor outputs (channels 1-4, microseconds).

        800 to 1,200 frames a simulated second: the time is read once before and once after the
        step, the body as a plain tuple, and the rotor commands are mapped again only when the
        outputs change."""
        st, scn, t0 = self.stepper, self.scn, self.t0
        if self.events is not None:  # the outputs ArduCopter sent for this frame, at its start
            self.events.after_outputs(st.t - t0, True, pwm)
        outputs = self._outputs
        if outputs is None or outputs[0] != pwm:
            self._outputs = outputs = (tuple(pwm), planar_rotor_commands(pwm))
        u_left, u_right = outputs[1]
        if not scn.wind.calm:
            st.set_external_force(*scn.wind.force_at(st.t - t0))
        st.step(dt, u_left, u_right)
        self.world.update(st)  # the surface under the position this frame reports
        self.roll.step(dt, pwm, st, self.world)
        self.yaw.step(dt, pwm, st, self.world)
        t = st.t - t0
        self._motion = m = st.motion()
        fx, fz = st.specific_force_body()
        imu = self.imu
        imu.accel_noise = scn.accel_noise + scn.imu_extra_noise(t)
        # ArduPilot filters the IMU itself (INS_*_FILTER): hand it the unfiltered reading
        r, p = self.yaw.rate, self.roll.rate
        if r or p:
            roll_rate, yaw_rate = p - r * math.sin(m[3]), r * math.cos(m[3])
            imu.update(dt, fx, fz, m[6], 0.0, 0.0, scn.imu_spike(t), roll_rate, yaw_rate)
        else:
            imu.update(dt, fx, fz, m[6], 0.0, 0.0, scn.imu_spike(t))
        true = self._trace_beam(m)  # NaN: the footprint straddles an edge
        status = 1 if math.isnan(true) else 4 if math.isfinite(true) else 3
        raw = Range(0.0, 1, 0) if status == 1 else Range(true, status, 100)
        self.range = scn.range_fault(t, raw, self.normals)
        if self.legs is not None:
            self.legs.update(self)
        if self.events is not None:
            self.events.after_physics_step(st, t, lambda: self._world_body(BodyState(*m)))
            if t >= self._truth_next:
                self._truth_next = t + TRUTH_PERIOD_S
                self._send_event("TR_H", t, self.height_m())

    def script_may_time(self) -> bool:
        """:func:`~slopelander_sitl.json_physics.companion_gate.script_may_time` for this frame's body and
        the last frame's motor outputs."""
        vz, rate = self._motion[5], self._motion[6]
        outputs = self._outputs
        return script_may_time(vz, rate, outputs is not None and min(outputs[1]) < 0.0)

    def height_m(self) -> float:
        """Height (m) of the body over the surface under it, this frame."""
        x, z = self.world.to_world(self._motion[1], self._motion[2])
        return z - self.world.surface_z(x)

    def _world_body(self, b):
        """Body ``b`` in world coordinates."""
        x, z = self.world.to_world(b.x, b.z)
        return replace(b, x=x, z=z)

    def _trace_beam(self, m: tuple[float, ...]) -> float:
        """:func:`world_beam` for the body's :meth:`~Stepper.motion` ``m``, traced again only
        once the body or the world under it has moved (:data:`BEAM_REUSE`)."""
        w, last = self.world, self._beam
        _t, x, z, pitch = m[:4]
        if (
            last is not None
            and abs(x - last[0]) < BEAM_REUSE
            and abs(z - last[1]) < BEAM_REUSE
            and abs(pitch - last[2]) < BEAM_REUSE
            and (w.ox, w.oz, w.on_roof, w.heading_deg, self.roll.angle) == last[3:8]
        ):
            return last[8]
        value = world_beam(self.stepper, w)
        phi = self.roll.angle
        if phi and math.isfinite(value) and value > 0.0:
            # the beam tilted sideways (to the body's left for a roll right) meets a surface falling
            # to the right at beta further: r = h / (cos(phi) + tan(beta) sin(phi)) for a slice's h
            beta = math.radians(w.section_slope_deg(90.0)) if w.on_roof else 0.0
            value = value / (math.cos(phi) + math.tan(beta) * math.sin(phi))
        self._beam = (x, z, pitch, w.ox, w.oz, w.on_roof, w.heading_deg, phi, value)
        return value

    def _rng_1(self) -> float:
        """The rangefinder value of the reply: NaN no data, far when nothing is in range."""
        r = self.range
        if r.status == 1:
            return NO_DATA_M
        if not math.isfinite(r.distance_m):
            return NO_RETURN_M
        return max(0.0, r.distance_m)

    def fdm(self) -> Fdm:
        """This frame's report."""
        _t, bx, bz, pitch, vx, vz, _q = self._motion
        w = self.world
        x, z = w.to_world(bx, bz)
        a, g = self.imu.accel, self.imu.gyro
        if self._turned():
            n, e = w.ne(x)
            c, s = w._dir()
            y, vy = self.roll.y, self.roll.v
            position = (n - y * s - self.home_ne[0], e + y * c - self.home_ne[1], -(z - self.home[1]))
            velocity = (vx * c - vy * s, vx * s + vy * c, -vz)
        else:
            position, velocity = (x - self.home[0], 0.0, -(z - self.home[1])), (vx, 0.0, -vz)
        return Fdm(
            timestamp=self.t,
            gyro=(float(g[0]), float(g[1]), float(g[2])),
            accel_body=(float(a[0]), float(a[1]), float(a[2])),
            position=position,
            velocity=velocity,
            attitude=(self.roll.angle, pitch, math.radians(wrap_deg(self.yaw.heading_deg))),
            rng_1=self._rng_1(),
        )

    def _full_reply(self) -> bytes:
        """:meth:`reply` for a vehicle that turned or rolls: ``encode_reply(self.fdm())``'s bytes
        from the floats, without the report."""
        _t, bx, bz, pitch, vx, vz, _q = self._motion
        w, a, g = self.world, self.imu.accel, self.imu.gyro
        x, z = w.to_world(bx, bz)
        n, e = w.ne(x)
        c, s = w._dir()
        y, vy = self.roll.y, self.roll.v
        values = (
            self.stepper.t - self.t0,
            *map(float, g),
            *map(float, a),
            n - y * s - self.home_ne[0],
            e + y * c - self.home_ne[1],
            -(z - self.home[1]),
            vx * c - vy * s,
            vx * s + vy * c,
            -vz,
            self.roll.angle,
            pitch,
            math.radians(wrap_deg(self.yaw.heading_deg)),
            float(self._rng_1()),
        )
        return encode_full_reply(values) or encode_reply(self.fdm())

    def _turned(self) -> bool:
        """Whether the vehicle has left the north axis it booted on, or rolls (the planar reply
        no longer says it)."""
        w = self.world
        return (
            self.yaw.heading_deg != 0.0
            or w.heading_deg != 0.0
            or w.e0 != 0.0
            or w.n0 != 0.0
            or self.roll.angle != 0.0
            or self.roll.v != 0.0
            or self.roll.y != 0.0
        )

    def reply(self) -> bytes:
        """``encode_reply(self.fdm())``, the same bytes, without building the report (a third of
        a frame's work at 800 frames a second); what encode_reply refuses goes through it, so it
        raises the same error."""
        if self._turned():
            return self._full_reply()
        _t, bx, bz, pitch, vx, vz, _q = self._motion
        world, home = self.world, self.home
        a, g = self.imu.accel, self.imu.gyro
        values = (
            self.stepper.t - self.t0,
            *g,
            *a,
            bx + world.ox - home[0],  # world.to_world, then from home, as fdm() does
            -(bz + world.oz - home[1]),
            vx,
            -vz,
            pitch,
            float(self._rng_1()),
        )
        return encode_planar_reply(values) or encode_reply(self.fdm())


def planar_rotor_commands(pwm: Sequence[float]) -> tuple[float, float]:
    """(left, right) rotor commands of the planar model for ArduCopter's four motor outputs: the
    rear pair the model's left (-x) rotor, the front pair its right (+x) rotor, each pair's command
    the one whose thrust (growing with the command's square) is the mean of its two motors'.
    ArduCopter mixes in thrust (MOT_THST_EXPO 1): it turns the vehicle by adding thrust to one
    diagonal pair and taking as much from the other, so motors asked for 0.35 and 0.15 of full
    thrust (commands 0.59 and 0.39) push what two at 0.25 do; the mean of the commands
    (:func:`slopelander_sitl.vehicle.esc.planar_rotor_commands`), 0.49, would push 4 % less, and the vehicle
    sank 0.66 m in a 90 deg turn on real ArduCopter. The same command when a pair's two are equal,
    as they are at rest and in every reverse thrust."""
    out = []
    for a, b in (esc.REAR, esc.FRONT):
        u, v = esc.pwm_to_command(pwm[a]), esc.pwm_to_command(pwm[b])
        if u == v:
            out.append(u)
            continue
        m = 0.5 * (u * abs(u) + v * abs(v))
        out.append(math.copysign(math.sqrt(abs(m)), m))
    return out[0], out[1]


def wrap_deg(angle: float) -> float:
    """An angle (deg) in -180..180."""
    return (angle + 180.0) % 360.0 - 180.0


class Roll:
    """The body's roll and its slide across the heading, outside the planar model: each motor's
    thrust as :class:`Yaw` has it, the roll torque the left pair's thrust less the right's at the
    model's ``rotor_arm`` (the F450's arm seen along the pitch axis, as the model's pitch has it),
    lagging by the rotors' time constant, over the model's pitch inertia (a quad X rolls as it
    pitches); the thrust the model's rotors give, tilted by the roll, pushes the body sideways. On
    the ground or close over it (where the world does not move its slice: :meth:`World.turn`)
    the body is level and still across."""

    def __init__(self, params) -> None:
        self.inertia = params["body_inertia"]
        self.arm = params["rotor_arm"]
        self.mass = params["body_mass"] + 2 * params["leg_mass"]
        self.thrust_max = 0.5 * params["rotor_thrust_max"]
        self.reverse = params["rotor_reverse_ratio"]
        self.tau = params["rotor_time_constant"]
        self.torque = 0.0  # N m, rolling right
        self.rate = 0.0  # rad/s
        self.angle = 0.0  # rad, right side down
        self.v = 0.0  # m/s, to the heading's right
        self.y = 0.0  # m to the right of the world's slice (moved onto a new one at SLIDE_STEP_M)

    def step(self, dt: float, pwm: Sequence[int], stepper: Stepper, world: World) -> None:
        want = 0.0
        for sign, p in zip(ROLL_SIGNS, pwm, strict=False):
            u = esc.pwm_to_command(p)
            want += sign * self.arm * self.thrust_max * u * abs(u) * (self.reverse if u < 0 else 1.0)
        self.torque += (want - self.torque) * min(1.0, dt / self.tau)
        _t, x, z = stepper.motion()[:3]
        a = math.radians(stepper.slope_deg)
        if stepper.in_contact() or x * math.sin(a) + z * math.cos(a) < CLEAR_M:
            self.rate = self.angle = self.v = 0.0
            return
        self.rate += self.torque / self.inertia * dt
        self.angle += self.rate * dt
        self.v += sum(stepper.thrust()) / self.mass * math.sin(self.angle) * dt
        self.y += self.v * dt
        if abs(self.y) >= SLIDE_STEP_M and world.turn(stepper, world.heading_deg, self.y):
            self.y = 0.0


class Yaw:
    """The heading, turned by the motors' drag torques: each motor's thrust from its command (the
    ESC mapping, thrust growing with the square of the command), its drag torque
    :data:`YAW_TORQUE_PER_THRUST_M` per newton with the sign of its spin (:data:`YAW_SIGNS`), the
    sum lagging the command by the rotors' time constant, over :data:`YAW_INERTIA_PER_PITCH` times
    the model's pitch inertia. The feet on the ground hold it (in contact, and below the height
    the world turns its plane at, the heading stays: :meth:`World.turn`)."""

    def __init__(self, params, roll: Roll) -> None:
        self.roll = roll  # a turn starts its new slice through the body where it slid to
        self.inertia = YAW_INERTIA_PER_PITCH * params["body_inertia"]
        self.thrust_max = 0.5 * params["rotor_thrust_max"]  # a planar rotor is a pair of motors
        self.reverse = params["rotor_reverse_ratio"]
        self.tau = params["rotor_time_constant"]
        self.torque = 0.0  # N m, clockwise seen from above (NED yaw)
        self.rate = 0.0  # rad/s
        self.heading_deg = 0.0

    def step(self, dt: float, pwm: Sequence[int], stepper: Stepper, world: World) -> None:
        want = 0.0
        for sign, p in zip(YAW_SIGNS, pwm, strict=False):
            u = esc.pwm_to_command(p)
            thrust = self.thrust_max * u * abs(u) * (self.reverse if u < 0 else 1.0)
            want += sign * YAW_TORQUE_PER_THRUST_M * thrust
        self.torque += (want - self.torque) * min(1.0, dt / self.tau)
        _t, x, z = stepper.motion()[:3]
        a = math.radians(stepper.slope_deg)
        if stepper.in_contact() or x * math.sin(a) + z * math.cos(a) < CLEAR_M:
            self.rate = 0.0  # on the ground or close over it: the world does not turn (World.turn)
            return
        self.rate += self.torque / self.inertia * dt
        heading = self.heading_deg + math.degrees(self.rate * dt)
        if abs(wrap_deg(heading - world.heading_deg)) >= SLICE_STEP_DEG:
            if not world.turn(stepper, heading, self.roll.y):
                self.rate = 0.0  # low over the surface: the world does not turn (see World.turn)
                return
            self.roll.y = 0.0
        self.heading_deg = heading % 360.0
