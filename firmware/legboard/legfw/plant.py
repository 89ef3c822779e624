"""The plant a host runs under the firmware: motor, lead screw, friction stack and leg; no I/O.

Per leg: a DC gear motor (winding resistance, back-EMF, rotor inertia; the inductance's
L/R ≈ 0.1 ms is far inside one 4 ms tick and left out) drives a self-locking lead screw
whose nut crosses a clearance and then compresses a Belleville stack onto 18 friction
surfaces (paper eq. 1); the joint turns against that friction under its reset spring, the
landing (angles set from outside) or a bench load. Every number is assumed except the
paper's (gear 1:298, n = 18, r_i, r_o, μ range, ≈10 s to clamp); docs/leg-protocol.md §6
lists them. Floats, and the same arithmetic on MicroPython and CPython: the noise comes from
a seeded xorshift generator, not ``random``, so both interpreters draw the same numbers.
"""

import math


class PlantParams:
    """Assumed parameters (SI). Keyword arguments override; ``mu`` is one value per leg."""

    r_winding = 1.9  # Ω
    k_motor = 1.0e-3  # N·m/A = V·s/rad
    i_no_load = 0.040  # A: the motor's own friction, as a current
    inertia = 1.0e-8  # kg·m², rotor and first gear stage seen at the motor shaft
    gear_ratio = 298.0  # paper
    gear_efficiency = 0.5
    screw_pitch = 0.3e-3  # m per revolution
    screw_efficiency = 0.2  # self-locking
    backdrive_factor = 0.3  # backing off needs this share of the forward torque per newton
    clearance = 2.9e-3  # m of nut travel before the stack is touched
    stack_stiffness = 35e3  # N/m
    stack_flat = 2.5e-3  # m of compression at which the stack is flat
    flat_stiffness = 2.0e6  # N/m beyond flat
    surfaces = 18  # paper
    r_inner = 3.3e-3  # paper
    r_outer = 13e-3  # paper
    mu = (0.270, 0.280, 0.265, 0.285)  # within the paper's 0.25–0.3
    mu_slope = 0.0  # relative change of μ per 100 N of clamping (0: Coulomb friction)
    spring_preload = 0.03  # N·m, reset spring at full extension
    spring_rate = 0.1  # N·m/rad
    reset_damping = 0.02  # N·m·s/rad
    loose_drag = 0.005  # N·m of disk drag when loose
    stop_force_limit = 0.5  # N·m the rest stop can push a leg down against
    noise_ma = 1.5  # σ of the current sense
    sense_lsb_ua = 730  # current sense resolution (the reference board: 12 bits over 3.3 V at 1.1 V/A)
    sense_range_ma = 3200  # current sense saturates here
    encoder_cpr = 3  # motor encoder counts per motor revolution (x1 decoding)
    angle_counts = 4096  # joint angle sensor (AS5600, 12 bit)
    r_short = 0.1  # Ω of a short across the motor terminals (fault "overcurrent")
    gear_skip = 0.3  # a skipping gear (fault "erratic") loses up to this share of the clamp at each stop
    grip_scatter = 0.3  # worn or greasy disks (fault "grip"): μ differs by up to this share per clamp
    start_travel = 0.0  # m of nut travel at power-up (a leg left clamped when the board was switched off)

    def __init__(self, **overrides) -> None:
        for key in overrides:
            if not hasattr(PlantParams, key) or key.startswith("_"):
                raise ValueError(f"unknown plant parameter {key!r}")
            setattr(self, key, overrides[key])
        if len(self.mu) != 4:
            raise ValueError("mu needs one value per leg")

    def amps_per_newton(self) -> float:
        """Forward motor current per newton of nut force (gear, screw, motor constant)."""
        return self.screw_pitch / (
            2 * math.pi * self.screw_efficiency * self.gear_ratio * self.gear_efficiency * self.k_motor
        )

    def torque_per_newton(self) -> float:
        """Paper eq. (1) without μ: τ = (2n/3)·μ·F·(r_o³ − r_i³)/(r_o² − r_i²)."""
        ro = self.r_outer
        ri = self.r_inner
        return 2 * self.surfaces / 3 * (ro**3 - ri**3) / (ro**2 - ri**2)

    def torque_at_current(self, leg: int, current_a: float) -> float:
        """The friction torque a clamp that ends at ``current_a`` gives (the plant's true curve)."""
        force = max(0.0, (current_a - self.i_no_load) / self.amps_per_newton())
        return self.torque_per_newton() * self.mu[leg] * (1.0 + self.mu_slope * force / 100.0) * force


class Noise:
    """xorshift32 and Box-Muller: the same normal deviates on every interpreter."""

    def __init__(self, seed: int) -> None:
        self.state = (seed * 2654435761 + 12345) & 0xFFFFFFFF or 1
        self.spare = None

    def uniform(self) -> float:
        x = self.state
        x ^= (x << 13) & 0xFFFFFFFF
        x ^= x >> 17
        x ^= (x << 5) & 0xFFFFFFFF
        self.state = x
        return (x + 0.5) / 4294967296.0

    def gauss(self) -> float:
        if self.spare is not None:
            z = self.spare
            self.spare = None
            return z
        r = math.sqrt(-2.0 * math.log(self.uniform()))
        a = 2.0 * math.pi * self.uniform()
        self.spare = r * math.sin(a)
        return r * math.cos(a)


class LegPlant:
    """One leg's mechanics; the HAL sets :attr:`volts` and reads the sensors."""

    def __init__(self, index: int, p: PlantParams) -> None:
        self.index = index
        self.p = p
        self.volts = 0.0  # applied by the H-bridge (0 = braked)
        self.omega = 0.0  # motor rad/s
        self.motor_rad = 0.0  # motor shaft angle (the encoder's)
        self.travel = p.start_travel  # m of nut travel from the back stop
        self.current = 0.0  # A, true, signed
        self.angle_deg = 37.5
        self.stop_deg = 37.5
        self.sensed_for = -1.0  # the angle the sensor's last reading is of
        self.sensed_cdeg = 0
        # injected faults
        self.stuck = False  # the drive is jammed
        self.slip = False  # a stripped gear: the motor turns, the nut does not
        self.shorted = False  # a short across the motor's terminals
        self.sense_dead = False  # the current sense reads zero
        self.erratic = False  # a gear that skips teeth under load
        self.grip = False  # disks whose grip differs from one clamp to the next
        self.grip_factor = 1.0
        # its own stream, drawn once a clamp (the nut reaching the stack): the same grips in the
        # same order however the board's clock and the sensor noise interleave
        self.grip_draws = Noise(1000 + index)
        # the calibration bench (docs/legs-build.md): a mass on a lever, a peg, the spring off
        self.load_nm = 0.0
        self.peg = False
        self.spring = True
        self.catch_deg = 0.0

    def force(self) -> float:
        p = self.p
        d = self.travel - p.clearance
        if d <= 0:
            return 0.0
        if d <= p.stack_flat:
            return p.stack_stiffness * d
        return p.stack_stiffness * p.stack_flat + p.flat_stiffness * (d - p.stack_flat)

    def friction_torque(self) -> float:
        """Friction torque the joint holds now (paper eq. 1 with this leg's μ)."""
        p = self.p
        f = self.force()
        return (
            p.torque_per_newton() * p.mu[self.index] * (1.0 + p.mu_slope * f / 100.0) * f * self.grip_factor
        )

    def step(self, dt: float, noise: Noise) -> None:
        self._motor(dt, noise)
        self._joint(dt)

    def _motor(self, dt: float, noise: Noise) -> None:
        p = self.p
        v = self.volts
        r = p.r_winding
        k = p.k_motor
        if self.shorted:  # the motor's terminals shorted: the driver's current bypasses it
            v = 0.0
        if self.stuck:
            self.omega = 0.0
            self.current = v / r
            return
        if v == 0.0 and self.omega == 0.0:
            self.current = self.volts / p.r_short if self.shorted else 0.0
            return
        force = self.force()
        tau_nl = k * p.i_no_load
        if self.slip:
            fwd = tau_nl
            back = tau_nl
        else:
            g = p.amps_per_newton()
            fwd = k * (p.i_no_load + g * force)
            back = k * (p.i_no_load + p.backdrive_factor * g * force)
        w = self.omega
        if w == 0.0:
            stall = k * v / r
            if stall > fwd:
                s = 1.0
            elif stall < -back and (self.travel > 0.0 or self.slip):
                s = -1.0
            else:  # the screw holds: stalled
                self.current = self.volts / p.r_short if self.shorted else v / r
                return
        else:
            s = 1.0 if w > 0 else -1.0
        load = fwd if s > 0 else back
        tau = p.inertia * r / (k * k)
        w_inf = (v - r * s * load / k) / k
        decay = math.exp(-dt / tau)
        w_new = w_inf + (w - w_inf) * decay
        if w_new * s <= 0.0:  # the rotor stops within the step (the screw's friction holds it)
            t0 = -tau * math.log(-w_inf / (w - w_inf)) if w != w_inf else dt
            turn = w_inf * t0 + (w - w_inf) * tau * (1.0 - math.exp(-t0 / tau))
            w_new = 0.0
            if self.erratic and s > 0 and force > 5.0:  # the gear skips back under the load
                self.travel -= p.gear_skip * noise.uniform() * force / p.stack_stiffness
        else:
            turn = w_inf * dt + (w - w_inf) * tau * (1.0 - decay)
        self.omega = w_new
        self.motor_rad += turn
        self.current = self.volts / p.r_short if self.shorted else (v - k * w_new) / r
        if not self.slip:
            before = self.travel
            self.travel += turn / (p.gear_ratio * 2.0 * math.pi) * p.screw_pitch
            if self.grip and before <= p.clearance < self.travel:  # the disks settle anew each clamp
                self.grip_factor = 1.0 - p.grip_scatter * self.grip_draws.uniform()
            if self.travel <= 0.0:  # the back stop
                self.travel = 0.0
                self.omega = 0.0

    def _joint(self, dt: float) -> None:
        """Reset spring (or a bench load) against the disk friction; the rest stop limits extension."""
        p = self.p
        if self.peg:
            return
        if self.angle_deg == self.stop_deg and self.spring and self.load_nm == 0.0:
            return  # at rest against its stop: the spring only presses it there
        friction = self.friction_torque() + p.loose_drag
        if self.angle_deg > self.stop_deg:
            if friction < p.stop_force_limit:
                self.angle_deg = self.stop_deg
            return
        net = -self.load_nm
        if self.spring:
            net += p.spring_preload + p.spring_rate * math.radians(37.5 - self.angle_deg)
        if net > friction:
            rate = math.degrees((net - friction) / p.reset_damping)
            self.angle_deg = min(self.stop_deg, self.angle_deg + rate * dt)
        elif -net > friction:
            rate = math.degrees((-net - friction) / p.reset_damping)
            self.angle_deg = max(self.catch_deg, self.angle_deg - rate * dt)


class Plant:
    """Four legs stepped together."""

    def __init__(self, params=None, seed: int = 0) -> None:
        self.p = params or PlantParams()
        self.noise = Noise(seed)
        self.legs = [LegPlant(i, self.p) for i in range(4)]

    def step(self, dt: float) -> None:
        for leg in self.legs:
            leg.step(dt, self.noise)

    def sensed_current_ua(self, leg: int) -> int:
        """The current sense: noise, resolution, range; zero when it is dead."""
        lg = self.legs[leg]
        p = self.p
        if lg.sense_dead or (lg.current == 0.0 and lg.volts == 0.0):
            return 0
        ua = lg.current * 1e6
        if lg.volts != 0.0 or lg.current != 0.0:
            ua += p.noise_ma * 1000.0 * self.noise.gauss()
        lsb = p.sense_lsb_ua
        ua = math.floor(ua / lsb + 0.5) * lsb
        limit = p.sense_range_ma * 1000
        return max(-limit, min(limit, ua))

    def encoder(self, leg: int) -> int:
        return math.floor(self.legs[leg].motor_rad * self.p.encoder_cpr / (2.0 * math.pi))

    def angle_cdeg(self, leg: int) -> int:
        """The joint's magnetic angle sensor, quantised to its counts per turn."""
        lg = self.legs[leg]
        if lg.angle_deg != lg.sensed_for:
            n = self.p.angle_counts
            counts = math.floor(lg.angle_deg / 360.0 * n + 0.5)
            lg.sensed_cdeg = math.floor(counts * 36000.0 / n + 0.5)
            lg.sensed_for = lg.angle_deg
        return lg.sensed_cdeg
