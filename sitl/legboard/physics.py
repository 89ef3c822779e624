"""Physics and firmware of the simulated leg board, stepped in board time; no I/O.

Per leg: a quasi-static DC gear motor on a self-locking lead screw whose nut crosses a
clearance and then compresses a Belleville stack onto 18 friction surfaces (paper eq. 1);
the board's current loop; the reset spring and the joint angle. Every number below is
assumed except those the paper gives (gear 1:298, n = 18, r_i, r_o, μ range, ≈10 s).
The table in ``docs/leg-protocol.md`` §6 lists them with their reasons.

A vehicle simulator can use :class:`LegBoardPhysics` in-process (``set_joint_angle``,
``friction_torque_nm``) or talk to the board process through its control channel.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

from slopelander.legs.messages import (
    MAX_ANGLE_CDEG,
    MAX_CURRENT_MA,
    N_LEGS,
    FaultCode,
    LegReport,
    LegState,
    NakCode,
)

MAX_ANGLE_DEG = MAX_ANGLE_CDEG / 100.0


@dataclass(frozen=True)
class BoardParams:
    """Assumed parameters of motor, screw, springs, disks and firmware (SI unless named)."""

    v_max: float = 3.0  # V, the board's drive limit
    r_winding: float = 1.9  # Ω
    k_motor: float = 1.0e-3  # N·m/A = V·s/rad
    i_no_load: float = 0.040  # A
    gear_ratio: float = 298.0  # paper
    gear_efficiency: float = 0.5
    screw_pitch: float = 0.3e-3  # m per revolution
    screw_efficiency: float = 0.2  # self-locking
    backdrive_factor: float = 0.3  # reverse current per newton, relative to forward
    clearance: float = 2.9e-3  # m of nut travel before the stack is touched
    stack_stiffness: float = 35e3  # N/m
    stack_flat: float = 2.5e-3  # m of compression at which the stack is flat
    flat_stiffness: float = 2.0e6  # N/m beyond flat
    surfaces: int = 18  # paper
    r_inner: float = 3.3e-3  # paper
    r_outer: float = 13e-3  # paper
    mu: tuple[float, ...] = (0.270, 0.280, 0.265, 0.285)  # within the paper's 0.25–0.3
    spring_preload: float = 0.03  # N·m, reset spring at full extension
    spring_rate: float = 0.1  # N·m/rad
    reset_damping: float = 0.02  # N·m·s/rad
    loose_drag: float = 0.005  # N·m of disk drag when loose
    stop_speed: float = 15.0  # °/s, rest stop actuator (assumed mechanism)
    stop_force_limit: float = 0.5  # N·m the rest stop can push against
    loop_gain: float = 2.8e5  # rad/s per A of current error near the target
    noise_ma: float = 1.5  # σ of the reported current
    # firmware
    band_ma: float = 2.0  # |current − target| counted as "on target"
    settle_s: float = 0.3  # on target this long → HOLDING
    endstop_a: float = 0.3  # reverse current that means "at the back stop"
    overcurrent_a: float = 1.8  # above the stall current: a fault
    min_travel_s: float = 1.0  # faster than this, the drive cannot have moved: STUCK
    motion_limit_s: float = 30.0  # longer than this: TIMEOUT
    short_a: float = 2.0  # current with a shorted winding (sensor saturates)

    @property
    def amps_per_newton(self) -> float:
        """Forward motor current per newton of nut force (gear, screw, motor constant)."""
        return self.screw_pitch / (
            2 * math.pi * self.screw_efficiency * self.gear_ratio * self.gear_efficiency * self.k_motor
        )

    @property
    def torque_per_newton(self) -> float:
        """Paper eq. (1) without μ: τ = (2n/3)·μ·F·(r_o³ − r_i³)/(r_o² − r_i²)."""
        ro, ri = self.r_outer, self.r_inner
        return 2 * self.surfaces / 3 * (ro**3 - ri**3) / (ro**2 - ri**2)


@dataclass(eq=False)
class Leg:
    """State of one leg; firmware state machine plus mechanics."""

    travel: float = 0.0  # m from the back stop
    angle_deg: float = MAX_ANGLE_DEG
    stop_deg: float = MAX_ANGLE_DEG
    state: LegState = LegState.LOOSE
    fault: FaultCode = FaultCode.NONE
    target_a: float = 0.0
    held_a: float = 0.0  # highest target since the nut was last at its back stop
    pending_a: float | None = None  # target to tighten to after loosening
    angle_goal_deg: float | None = None  # SET_ANGLE goal while POSITIONING
    current: float = 0.0  # A, true (signed)
    phase_s: float = 0.0
    settled_s: float = 0.0
    from_loose: bool = False
    stuck: bool = False
    slip: bool = False
    shorted: bool = False


@dataclass
class LegBoardPhysics:
    """Four legs and the board firmware, advanced by :meth:`step` in board seconds."""

    params: BoardParams = field(default_factory=BoardParams)
    seed: int = 0
    time_s: float = 0.0
    legs: list[Leg] = field(default_factory=lambda: [Leg() for _ in range(N_LEGS)])

    def __post_init__(self) -> None:
        self._rng = random.Random(self.seed)

    # ---- commands (from the protocol) -------------------------------------------------
    def set_friction(self, leg: int, target_ma: int) -> NakCode | None:
        lg = self.legs[leg]
        if lg.state is LegState.FAULT:
            return NakCode.FAULTED
        if target_ma == 0:
            return self.loosen(leg)
        target = target_ma / 1000.0
        if lg.state is LegState.POSITIONING or lg.state is LegState.LOOSENING:
            lg.pending_a = target
        elif lg.state is LegState.LOOSE:
            lg.target_a, lg.held_a = target, target
            self._enter(lg, LegState.TIGHTENING)
            lg.from_loose = True
        elif target == lg.target_a and lg.state is not LegState.STOPPED:
            pass  # a repeated command does not restart the motion
        elif target >= lg.held_a:
            lg.target_a, lg.held_a = target, target
            self._enter(lg, LegState.TIGHTENING)
        else:  # self-locking screw: loosen first, then tighten to the lower target
            lg.pending_a = target
            self._enter(lg, LegState.LOOSENING)
        return None

    def loosen(self, leg: int) -> None:
        lg = self.legs[leg]
        lg.pending_a = None
        lg.fault = FaultCode.NONE
        if lg.state is LegState.LOOSE:
            return None
        if lg.state is LegState.FAULT and lg.travel <= self.params.clearance and not lg.stuck:
            # the nut still in its free clearance (a leg that faulted before it clamped): it is
            # loose already, and driving it back to the stop at once would read as a jam, so a
            # faulted leg could never be loosened (found by the soak)
            lg.travel = 0.0
            self._enter(lg, LegState.LOOSENING)
            self._at_back_stop(lg)
            return None
        if lg.state is not LegState.LOOSENING:
            self._enter(lg, LegState.LOOSENING)
        return None

    def set_angle(self, leg: int, angle_cdeg: int) -> NakCode | None:
        lg = self.legs[leg]
        if lg.state is LegState.FAULT:
            return NakCode.FAULTED
        lg.angle_goal_deg = angle_cdeg / 100.0
        lg.pending_a = None
        if lg.state is not LegState.POSITIONING:
            self._enter(lg, LegState.POSITIONING)
        return None

    def stop(self, leg: int) -> None:
        lg = self.legs[leg]
        if lg.state is not LegState.FAULT:
            lg.pending_a = None
            self._enter(lg, LegState.STOPPED)

    # ---- the vehicle side -------------------------------------------------------------
    def set_joint_angle(self, leg: int, angle_deg: float) -> None:
        """Move a joint from outside (landing compression fed by the vehicle simulator)."""
        lg = self.legs[leg]
        lg.angle_deg = min(max(float(angle_deg), 0.0), lg.stop_deg)

    def friction_torque_nm(self, leg: int) -> float:
        """Friction torque the joint holds now (paper eq. 1 with this leg's μ)."""
        p = self.params
        return p.torque_per_newton * p.mu[leg] * self.nut_force(self.legs[leg])

    def inject(self, kind: str, leg: int) -> None:
        """Mechanical/electrical faults: ``stuck``, ``slip``, ``overcurrent``."""
        setattr(self.legs[leg], {"overcurrent": "shorted"}.get(kind, kind), True)

    def clear_faults(self) -> None:
        for lg in self.legs:
            lg.stuck = lg.slip = lg.shorted = False

    # ---- reports ----------------------------------------------------------------------
    def reports(self) -> tuple[LegReport, ...]:
        """STATUS contents: the current as the board measures it (with noise)."""
        out = []
        for lg in self.legs:
            noisy = lg.current * 1000.0 + self._rng.gauss(0.0, self.params.noise_ma)
            current = max(-MAX_CURRENT_MA, min(MAX_CURRENT_MA, round(noisy)))
            out.append(
                LegReport(
                    lg.state,
                    lg.fault,
                    current,
                    round(lg.target_a * 1000) if lg.state in _DRIVING else 0,
                    round(lg.angle_deg * 100),
                )
            )
        return tuple(out)

    # ---- physics ----------------------------------------------------------------------
    def nut_force(self, lg: Leg) -> float:
        p = self.params
        d = lg.travel - p.clearance
        if d <= 0:
            return 0.0
        if d <= p.stack_flat:
            return p.stack_stiffness * d
        return p.stack_stiffness * p.stack_flat + p.flat_stiffness * (d - p.stack_flat)

    def step(self, dt: float) -> None:
        for i, lg in enumerate(self.legs):
            self._step_leg(i, lg, dt)
        self.time_s += dt

    def _enter(self, lg: Leg, state: LegState) -> None:
        lg.from_loose = False
        lg.state = state
        lg.phase_s = 0.0
        lg.settled_s = 0.0

    def _fail(self, lg: Leg, fault: FaultCode) -> None:
        self._enter(lg, LegState.FAULT)
        lg.fault = fault
        lg.pending_a = None

    def _step_leg(self, i: int, lg: Leg, dt: float) -> None:
        p = self.params
        force = self.nut_force(lg)
        omega = 0.0  # motor shaft speed, rad/s
        st = lg.state
        if st in (LegState.TIGHTENING, LegState.HOLDING):
            omega, lg.current = self._drive_forward(lg, force)
        elif st is LegState.LOOSENING or (st is LegState.POSITIONING and lg.travel > 0):
            omega, lg.current = self._drive_back(lg, force)
        else:
            lg.current = 0.0
        if lg.shorted and st in _DRIVING:
            lg.current = math.copysign(p.short_a, lg.current or 1.0)
        if not lg.stuck and not lg.slip:
            nut_speed = omega / p.gear_ratio * p.screw_pitch / (2 * math.pi)
            lg.travel = max(0.0, lg.travel + nut_speed * dt)
        lg.phase_s += dt
        self._firmware(lg, dt)
        self._move_joint(i, lg, dt)

    def _drive_forward(self, lg: Leg, force: float) -> tuple[float, float]:
        p = self.params
        if lg.slip:  # stripped gear: the motor spins unloaded
            return 0.0, min(lg.target_a, p.i_no_load)
        if lg.stuck:  # jammed: stalled, the loop holds the current on target
            return 0.0, lg.target_a
        i_fwd = p.i_no_load + p.amps_per_newton * force
        error = lg.target_a - i_fwd
        if error <= 0:  # the screw holds; the loop keeps the stalled current on target
            return 0.0, lg.target_a
        free = (p.v_max - p.r_winding * i_fwd) / p.k_motor
        return max(0.0, min(free, p.loop_gain * error)), i_fwd

    def _drive_back(self, lg: Leg, force: float) -> tuple[float, float]:
        p = self.params
        stall = -p.v_max / p.r_winding
        if lg.stuck:
            return 0.0, stall
        if lg.slip:
            return 0.0, -p.i_no_load
        if lg.travel <= 0.0:
            return 0.0, stall
        i_back = p.i_no_load + p.backdrive_factor * p.amps_per_newton * force
        return -(p.v_max - p.r_winding * i_back) / p.k_motor, -i_back

    def _firmware(self, lg: Leg, dt: float) -> None:
        p = self.params
        st = lg.state
        if st in _DRIVING and abs(lg.current) > p.overcurrent_a:
            self._fail(lg, FaultCode.OVERCURRENT)
            lg.current = 0.0
            return
        if st in _DRIVING and st is not LegState.HOLDING and lg.phase_s > p.motion_limit_s:
            self._fail(lg, FaultCode.TIMEOUT)
            return
        if st is LegState.TIGHTENING or st is LegState.HOLDING:
            on_target = abs(lg.current - lg.target_a) * 1000.0 <= p.band_ma
            first_on_target = on_target and lg.settled_s == 0.0 and st is LegState.TIGHTENING
            if first_on_target and lg.from_loose and lg.phase_s < p.min_travel_s:
                self._fail(lg, FaultCode.STUCK)
                return
            lg.settled_s = lg.settled_s + dt if on_target else 0.0
            if st is LegState.TIGHTENING and lg.settled_s >= p.settle_s:
                lg.state = LegState.HOLDING
        elif (st is LegState.LOOSENING or st is LegState.POSITIONING) and (lg.current < -p.endstop_a):
            if lg.phase_s < p.min_travel_s:
                self._fail(lg, FaultCode.STUCK)
                return
            lg.held_a = 0.0
            lg.travel = 0.0
            if st is LegState.LOOSENING:
                self._at_back_stop(lg)
        elif st is LegState.POSITIONING and lg.travel <= 0.0:
            self._move_stop(lg, dt)

    def _at_back_stop(self, lg: Leg) -> None:
        lg.current = 0.0
        if lg.pending_a is not None:
            lg.target_a, lg.held_a = lg.pending_a, lg.pending_a
            lg.pending_a = None
            self._enter(lg, LegState.TIGHTENING)
        else:
            self._enter(lg, LegState.LOOSE)

    def _move_stop(self, lg: Leg, dt: float) -> None:
        goal = lg.angle_goal_deg if lg.angle_goal_deg is not None else lg.stop_deg
        step = self.params.stop_speed * dt
        lg.stop_deg += max(-step, min(step, goal - lg.stop_deg))
        if lg.stop_deg == goal and abs(lg.angle_deg - goal) < 0.2:
            lg.angle_goal_deg = None
            pending = lg.pending_a
            self._enter(lg, LegState.LOOSE)
            if pending is not None:
                lg.target_a, lg.held_a = pending, pending
                self._enter(lg, LegState.TIGHTENING)
                lg.from_loose = True

    def _move_joint(self, i: int, lg: Leg, dt: float) -> None:
        """Reset spring against the disk friction; the rest stop limits extension."""
        p = self.params
        friction = self.friction_torque_nm(i) + p.loose_drag
        if lg.angle_deg > lg.stop_deg:
            if friction < p.stop_force_limit:
                lg.angle_deg = lg.stop_deg
            return
        spring = p.spring_preload + p.spring_rate * math.radians(MAX_ANGLE_DEG - lg.angle_deg)
        if spring > friction:
            rate = math.degrees((spring - friction) / p.reset_damping)
            lg.angle_deg = min(lg.stop_deg, lg.angle_deg + rate * dt)


_DRIVING = (LegState.TIGHTENING, LegState.HOLDING, LegState.LOOSENING, LegState.POSITIONING)
