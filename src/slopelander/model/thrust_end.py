"""A landing under reverse thrust that ends the thrust once the vehicle reads still, and what
the feet do after.

This is the companion's REVERSE state flown on the model alone (no processes): 100 % reverse
thrust from impact, ended once the body has been still for ``still_s`` (at least ``min_s`` after
impact, at most ``max_s``), either as a step to zero or as a linear ramp of the rotor command
over ``ramp_s``. It records, per foot, the normal and tangential contact force, the foot's
friction limit, the legs' and joints' angles and the body's height, so that the moment a foot
breaks away can be read off (``docs/model.md``, "When the reverse thrust ends").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slopelander.model import kernel as k
from slopelander.model.conditions import ConditionError, LandingConditions
from slopelander.model.landing import Model
from slopelander.model.stepper import Stepper

CONTROL_DT = 1.0 / 200.0  # s: the companion's IMU rate; thrust commands change at this rate


@dataclass(frozen=True)
class ThrustEnd:
    """When and how the reverse thrust ends (the companion's `reflex.*` and `settle.*` keys)."""

    ramp_s: float = 0.0
    """0 = the command steps to zero; otherwise it falls linearly to zero over this time."""
    min_s: float = 0.5
    still_s: float = 0.2
    still_speed: float = 0.05
    max_s: float = 3.0

    def __post_init__(self) -> None:
        for name in ("ramp_s", "min_s", "still_s", "still_speed", "max_s"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0.0 or v > 10.0:
                raise ConditionError(name, v, "must lie within 0..10")
        if self.max_s < self.min_s:
            raise ConditionError("max_s", self.max_s, "must not be below min_s")

    def command(self, since_end: float, full: float) -> float:
        """Rotor command ``since_end`` seconds after the thrust began to end (``full`` is < 0)."""
        if self.ramp_s <= 0.0:
            return 0.0
        return full * max(0.0, 1.0 - since_end / self.ramp_s)


@dataclass(frozen=True)
class AfterThrust:
    """What happened from the moment the thrust began to end. Arrays hold one row per control
    tick; per-foot columns are (uphill, downhill). Tangential forces are downhill-positive
    forces of the surface on the foot: a foot held against sliding downhill reads negative."""

    ended_at: float
    """Seconds after first contact when the thrust began to end."""
    t: np.ndarray
    command: np.ndarray
    thrust: np.ndarray
    normal: np.ndarray
    tangential: np.ndarray
    sliding: np.ndarray
    """True while the foot slips."""
    leg_deg: np.ndarray
    joint_deg: np.ndarray
    height: np.ndarray
    """Centre of mass above the surface, along its normal (m)."""
    downhill: np.ndarray
    """Centre of mass moved down the slope since the thrust began to end (m)."""
    speed: np.ndarray
    mu_static: float

    def demand(self) -> np.ndarray:
        """|F_t| / N per foot: the friction a foot needs, against its static limit mu_s."""
        return np.abs(self.tangential) / np.maximum(self.normal, 1e-9)

    def first_slip(self) -> tuple[float, float]:
        """Seconds after the thrust began to end at which each foot (uphill, downhill) first
        slipped; nan if it never did."""
        out = []
        for f in range(2):
            i = np.flatnonzero(self.sliding[:, f])
            out.append(float(self.t[i[0]]) if i.size else math.nan)
        return out[0], out[1]

    @property
    def slide(self) -> float:
        return float(self.downhill[-1])

    def held(self, tolerance: float = 0.02) -> bool:
        """Still at the end and moved less than ``tolerance`` m down the slope."""
        return abs(self.slide) < tolerance and float(self.speed[-1]) < 0.01


def land_and_end_thrust(
    conditions: LandingConditions,
    end: ThrustEnd | None = None,
    model: Model | None = None,
    after_s: float = 2.0,
) -> AfterThrust:
    """Land with ``conditions`` (its ``reverse_percent`` from impact), end the thrust as ``end``
    says, and record ``after_s`` seconds past the end of the ramp."""
    end = end or ThrustEnd()
    model = model or Model.default()
    conditions.validate(model.params.angle_min_deg, model.params.angle_max_deg)
    if conditions.reverse_percent <= 0.0:
        raise ConditionError("reverse_percent", conditions.reverse_percent, "there is no thrust to end")
    s = Stepper(model, slope_deg=conditions.slope_deg)
    s.start_landing(conditions)
    full = -conditions.reverse_percent / 100.0
    a = math.radians(conditions.slope_deg)
    n_hat = (math.sin(a), math.cos(a))
    t_hat = (math.cos(a), -math.sin(a))
    up, dn = 1 - s.downhill, s.downhill
    u, still, ended, x0 = 0.0, 0.0, math.nan, (0.0, 0.0)
    rows: list[tuple[float, ...]] = []
    t_contact = math.nan
    while True:
        if math.isnan(t_contact) and s.st[k.S_TIMP] >= 0.0:
            t_contact = float(s.st[k.S_TIMP])
        if not math.isnan(t_contact):
            since = s.t - t_contact
            if math.isnan(ended):
                u = full if since >= conditions.reverse_delay else 0.0
            else:
                u = end.command(since - ended, full)
        s.step(CONTROL_DT, u, u)
        b = s.body()
        speed = math.hypot(b.vx, b.vz)
        if math.isnan(t_contact):
            if s.t > 5.0:
                raise ConditionError("speed", conditions.speed, "no contact within 5 s")
            continue
        since = s.t - t_contact
        if math.isnan(ended):
            still = still + CONTROL_DT if speed <= end.still_speed else 0.0
            if (since >= end.min_s and still >= end.still_s - 1e-9) or since >= end.max_s:
                ended, x0 = since, (b.x, b.z)
            continue
        st = s.st
        rows.append(
            (
                since - ended,
                u,
                float(st[k.S_THR] + st[k.S_THR + 1]),
                st[k.S_NF + up],
                st[k.S_NF + dn],
                st[k.S_FT + up],
                st[k.S_FT + dn],
                float(st[k.S_CM + up] >= 2.0),
                float(st[k.S_CM + dn] >= 2.0),
                *s.leg_angles_deg(),
                *s.joint_angles_deg(),
                n_hat[0] * b.x + n_hat[1] * b.z,
                t_hat[0] * (b.x - x0[0]) + t_hat[1] * (b.z - x0[1]),
                speed,
            )
        )
        if since - ended > end.ramp_s + after_s:
            break
    r = np.array(rows)
    sign = 1.0 if conditions.slope_deg >= 0.0 else -1.0
    return AfterThrust(
        ended_at=ended,
        t=r[:, 0],
        command=r[:, 1],
        thrust=r[:, 2],
        normal=r[:, 3:5],
        tangential=sign * r[:, 5:7],
        sliding=r[:, 7:9] > 0.5,
        leg_deg=r[:, 9:11],
        joint_deg=r[:, 11:13],
        height=r[:, 13],
        downhill=sign * r[:, 14],
        speed=r[:, 15],
        mu_static=float(model.params["friction_static"]),
    )
