"""Cascaded planar flight control: position -> velocity -> pitch angle -> pitch rate -> the
two rotor pairs. Gains are in SI units and chosen for the model's F450 (rotor time constant
50 ms); they stand in for ArduPilot's tuned PSC_/ATC_ loops, not copy them."""

from __future__ import annotations

import math
from dataclasses import dataclass

from slopelander.model.stepper import BodyState


@dataclass
class Target:
    """What the mode asks for (world frame, z up). Position wins over velocity per axis when set;
    ``pitch``/``throttle`` (0..1) are the pilot's direct demands in STABILIZE."""

    x: float | None = None
    z: float | None = None
    vx: float = 0.0
    vz: float = 0.0
    pitch: float | None = None
    throttle: float | None = None


@dataclass
class Gains:
    pos_xy: float = 1.0
    vel_xy: float = 1.8
    vel_xy_i: float = 0.4
    pos_z: float = 1.2
    vel_z: float = 4.0
    vel_z_i: float = 2.0
    angle: float = 7.0
    rate: float = 25.0
    max_rate: float = 3.0  # rad/s
    max_vxy: float = 5.0
    max_vz_up: float = 2.5
    max_vz_dn: float = 1.5
    leash_z: float = 1.0  # m: how far a velocity target's moving height may run ahead of the vehicle


class FlightControl:
    """Turns a Target into per-pair thrust (N): returns (front, rear) and the collective used."""

    def __init__(self, mass: float, inertia: float, arm: float, gravity: float, thrust_max: float) -> None:
        self.m, self.inertia, self.arm, self.g, self.tmax = mass, inertia, arm, gravity, thrust_max
        self.gains = Gains()
        self.reset()

    def reset(self) -> None:
        self.ix = 0.0
        self.iz = 0.0
        self.throttle = 0.0  # collective as a fraction of full thrust, last tick
        self.demand = 0.0  # the same before the clamp at zero (negative: the controller wants less)
        self.pitch_target = 0.0  # rad, last tick's attitude target
        self.vz_desired = 0.0  # m/s, last tick's desired climb rate
        self.z_moving: float | None = None  # height a vertical velocity target moves (as AC_PosControl)

    def update(self, dt: float, b: BodyState, t: Target, angle_max: float) -> tuple[float, float]:
        k = self.gains
        # horizontal: position -> velocity -> acceleration -> pitch
        if t.pitch is not None:
            pitch_t = t.pitch
        else:
            vx_t = t.vx if t.x is None else k.pos_xy * (t.x - b.x)
            vx_t = max(-k.max_vxy, min(k.max_vxy, vx_t))
            ex = vx_t - b.vx
            self.ix = max(-2.0, min(2.0, self.ix + k.vel_xy_i * ex * dt))
            ax = k.vel_xy * ex + self.ix
            pitch_t = -math.atan2(ax, self.g)
        pitch_t = max(-angle_max, min(angle_max, pitch_t))
        self.pitch_target = pitch_t
        # vertical: position -> velocity -> acceleration -> collective thrust
        c = max(0.5, math.cos(b.pitch))
        if t.throttle is not None:
            collective = 2.0 * self.tmax * t.throttle
        else:
            if t.z is None:
                # a velocity target moves a height target along (AC_PosControl::input_vel_accel_z),
                # so a descent blocked by the ground keeps asking for less thrust
                z0 = b.z if self.z_moving is None else self.z_moving
                self.z_moving = max(b.z - k.leash_z, min(b.z + k.leash_z, z0 + t.vz * dt))
                vz_t = t.vz + k.pos_z * (self.z_moving - b.z)
            else:
                self.z_moving = None
                vz_t = k.pos_z * (t.z - b.z)
            vz_t = max(-k.max_vz_dn, min(k.max_vz_up, vz_t))
            self.vz_desired = vz_t
            ez = vz_t - b.vz
            self.iz = max(-self.g, min(6.0, self.iz + k.vel_z_i * ez * dt))
            az = k.vel_z * ez + self.iz
            collective = self.m * (self.g + az) / c
        if t.throttle is not None:
            self.vz_desired = 0.0
        self.demand = collective / (2.0 * self.tmax)
        collective = max(0.0, min(2.0 * self.tmax, collective))
        # attitude: angle -> rate -> torque -> differential thrust
        rate_t = max(-k.max_rate, min(k.max_rate, k.angle * (pitch_t - b.pitch)))
        torque = self.inertia * k.rate * (rate_t - b.pitch_rate)
        diff = torque / (2.0 * self.arm)
        diff = max(-0.5 * collective - 1.0, min(0.5 * collective + 1.0, diff))
        self.throttle = collective / (2.0 * self.tmax)
        return 0.5 * collective + diff, 0.5 * collective - diff

    def settle_on_ground(self) -> None:
        """Forget integrators while spooled down on the ground (as ArduCopter's relax on land)."""
        self.ix = 0.0
        self.iz = min(self.iz, 0.0)
        self.z_moving = None
