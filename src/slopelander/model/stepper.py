"""The model as a stepper: advance the vehicle by dt given rotor commands and leg settings.

This is what a simulated vehicle runs at ArduPilot's 1200 Hz physics rate: flight with
thrust, touchdown, and the legs' friction presets changed on the fly. Each ``step`` runs as
many sub-steps of the model's own ``dt`` as fit in the requested interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slopelander.model import kernel as k
from slopelander.model.conditions import CONDITION_FIELDS, ConditionError, LandingConditions
from slopelander.model.dispatch import call, entry
from slopelander.model.effects import memory_values
from slopelander.model.landing import Model
from slopelander.model.usercode import compiling_notice

ENERGY_TERMS = ("kinetic", "gravity", "ground_spring", "stiction_spring", "flex_spring", "eot_spring")
#: the state's indices read on every step, bound once (a module attribute costs a lookup a use)
_S_T, _S_Q, _S_V = k.S_T, k.S_Q, k.S_V
_S_NF, _S_NF_END = k.S_NF, k.S_NF + k.N_POINTS
#: the state's leading entries that hold position and velocity: read as one slice
_HEAD = max(k.S_Q, k.S_V) + 3

DISSIPATION_TERMS = (
    "joint_friction",
    "flex_damper",
    "eot_damper",
    "ground_damper",
    "foot_friction",
    "rotor_work",
    "user_effects",
)


@dataclass(frozen=True)
class BodyState:
    """Where the body is and how it moves (SI units, pitch in rad, x downhill, z up)."""

    t: float
    x: float
    z: float
    pitch: float
    vx: float
    vz: float
    pitch_rate: float


class Stepper:
    """A planar vehicle on a slope that can fly, land and be stepped in real time."""

    def __init__(self, model: Model | None = None, slope_deg: float = 0.0) -> None:
        self.model = model or Model.default()
        if not -75.0 <= slope_deg <= 75.0:
            raise ConditionError("slope_deg", slope_deg, "must lie within -75..75 deg")
        self._p = self.model.params.as_array()
        self._fl = self.model.flags()
        self._k, self._sx = self.model.kernel()
        if self._sx is None:  # no user effects: the integrator compiled without seams
            self._box = None
            self._advance = k.advance
        else:
            from slopelander.model.boxed import advance_boxed, box  # compiles on first use: not at import

            self._box = box(self._sx)
            self._advance = advance_boxed
        self._compiled = False
        self._entry = None  # the compiled step, looked up once (model/dispatch.py)
        self._ws = k.make_workspace()
        self.st = np.zeros(k.N_STATE)
        self.ctx = np.zeros(k.N_CTX)
        a = math.radians(slope_deg)
        self.ctx[k.C_SIN] = math.sin(a)
        self.ctx[k.C_COS] = math.cos(a)
        self.ctx[k.C_DOWN] = 1 if a >= 0 else 0
        self.slope_deg = slope_deg
        self._accel = (0.0, 0.0)  # over the last step, world (x, z): plain floats, read per step
        self._gravity = self.model.params["gravity"]
        amax = self.model.params.angle_max_deg
        self.set_leg_angles(amax, amax)
        self.set_friction(1.7, 1.7)
        self.st[k.S_DIR] = 1.0
        self.st[k.S_DIR + 1] = 1.0
        self.st[k.S_TIMP] = -1.0
        self._start_memory()
        self.place(height=1.0)

    def _start_memory(self) -> None:
        """The user effects' memory at its initial values."""
        init = memory_values(self.model.user_effects)
        self.st[k.S_MEM : k.S_MEM + len(init)] = init

    # -- set-up ------------------------------------------------------------------------------
    @property
    def downhill(self) -> int:
        return int(self.ctx[k.C_DOWN])

    def set_friction(self, tau_up: float, tau_down: float) -> None:
        """Friction torque per real joint (N*m) of the uphill and downhill pairs."""
        for name, v in (("tau_up", tau_up), ("tau_down", tau_down)):
            if not (0.0 <= v <= 10.0) or not math.isfinite(v):
                raise ConditionError(name, v, "must lie within 0..10 N*m")
        nj = self.model.params["joints_per_planar_leg"]
        self.ctx[k.C_TAU + 1 - self.downhill] = tau_up * nj
        self.ctx[k.C_TAU + self.downhill] = tau_down * nj

    def set_leg_angles(self, angle_up_deg: float, angle_down_deg: float) -> None:
        """Reset both legs to these angles (what the springs do once the joints are loose)."""
        lo, hi = self.model.params.angle_min_deg, self.model.params.angle_max_deg
        for name, v in (("angle_up_deg", angle_up_deg), ("angle_down_deg", angle_down_deg)):
            if not lo <= v <= hi:
                raise ConditionError(name, v, f"must lie within {lo}..{hi} deg")
        for j, v in ((1 - self.downhill, angle_up_deg), (self.downhill, angle_down_deg)):
            q = math.radians(v)
            self.st[k.S_Q + 3 + j] = q
            self.st[k.S_QE + j] = q
            self.st[k.S_V + 3 + j] = 0.0
            self.st[k.S_JM + j] = 0.0
            self.st[k.S_QEMIN + j] = q
            self.ctx[k.C_QINIT + j] = q

    def set_external_force(self, fx: float = 0.0, fz: float = 0.0, torque: float = 0.0) -> None:
        """A force on the body at its centre of mass (world x, z in N) and a pitch torque
        (N*m), held until changed: how a simulated vehicle feels wind gusts."""
        for name, v in (("fx", fx), ("fz", fz), ("torque", torque)):
            if not math.isfinite(v) or abs(v) > 100.0:
                raise ConditionError(name, v, "must be finite and within +-100")
        self.ctx[k.C_FEXT] = fx
        self.ctx[k.C_FEXT + 1] = fz
        self.ctx[k.C_FEXT + 2] = torque

    def place(
        self,
        height: float,
        x: float = 0.0,
        pitch_deg: float = 0.0,
        vx: float = 0.0,
        vz: float = 0.0,
        pitch_rate_dps: float = 0.0,
        rotor_speed: float = 0.0,
    ) -> None:
        """Put the vehicle with its lowest point ``height`` m above the surface (measured
        along the surface normal), at rest or moving, rotors spinning at ``rotor_speed``."""
        st = self.st
        st[k.S_Q] = x
        st[k.S_Q + 1] = 0.0
        st[k.S_Q + 2] = math.radians(pitch_deg)
        st[k.S_V] = vx
        st[k.S_V + 1] = vz
        st[k.S_V + 2] = math.radians(pitch_rate_dps)
        lowest = min(self._clearances())
        st[k.S_Q + 1] = (height - lowest) / self.ctx[k.C_COS]
        st[k.S_W] = rotor_speed
        st[k.S_W + 1] = rotor_speed
        st[k.S_CM : k.S_CM + k.N_POINTS] = 0.0

    def start_landing(self, conditions: LandingConditions) -> None:
        """Put the vehicle at the moment of impact exactly as ``simulate`` starts a landing
        (slope, leg presets, impact velocity); the rotor commands stay the caller's."""
        p = self.model.params
        conditions.validate(p.angle_min_deg, p.angle_max_deg)
        row = np.array([getattr(conditions, n) for n in CONDITION_FIELDS], dtype=np.float64)
        k.init_landing(self._p, self._fl, row, self.st, self.ctx, self._ws)
        if self._sx is not None:  # memory at its start; the feet's pads (if any) just touching
            k.start_user_effects(self._p, self._fl, self.ctx, self.st, self._ws, self._sx)
        self.slope_deg = conditions.slope_deg

    def set_slope(self, slope_deg: float, shift_x: float = 0.0, shift_z: float = 0.0) -> None:
        """Fly over onto another surface: set its slope and move the vehicle by (-shift_x,
        -shift_z) so that the new surface passes through the origin. Only while airborne,
        since a contact's anchors belong to the old surface."""
        if self.in_contact():
            raise ConditionError("slope_deg", slope_deg, "cannot change the surface while in contact")
        if not -75.0 <= slope_deg <= 75.0:
            raise ConditionError("slope_deg", slope_deg, "must lie within -75..75 deg")
        a = math.radians(slope_deg)
        if (1 if a >= 0 else 0) != self.downhill:
            raise ConditionError("slope_deg", slope_deg, "must keep the downhill side of the current surface")
        self.ctx[k.C_SIN] = math.sin(a)
        self.ctx[k.C_COS] = math.cos(a)
        self.slope_deg = slope_deg
        self.st[k.S_Q] -= shift_x
        self.st[k.S_Q + 1] -= shift_z
        self.st[k.S_CM : k.S_CM + k.N_POINTS] = 0.0

    def hover_command(self) -> float:
        """Rotor command that holds a level vehicle in the air."""
        p = self.model.params
        weight = (p["body_mass"] + 2 * p["leg_mass"]) * p["gravity"]
        return math.sqrt(weight / 2.0 / p["rotor_thrust_max"])

    # -- running -----------------------------------------------------------------------------
    def step(self, dt: float, u_left: float, u_right: float) -> None:
        """Advance by ``dt`` seconds with rotor commands in [-1, 1] (left = -x side)."""
        if not (0.0 < dt <= 1.0) or not math.isfinite(dt):
            raise ValueError(f"dt = {dt} s must lie in (0, 1]")
        # min(1.0, max(-1.0, u)) without the calls, NaN included (it reads -1)
        u_left, u_right = float(u_left), float(u_right)
        u_left = u_left if u_left > -1.0 else -1.0
        u_left = u_left if u_left < 1.0 else 1.0
        u_right = u_right if u_right > -1.0 else -1.0
        u_right = u_right if u_right < 1.0 else 1.0
        n = max(1, math.ceil(dt / self.model.dt - 1e-9))
        st = self.st
        v0x, v0z = st.item(_S_V), st.item(_S_V + 1)
        args = (self._p, self._fl, self.ctx, st, dt / n, n, u_left, u_right, self._ws, self._box)
        if self._entry is not None:
            # the arrays are this stepper's own, made once; the rest are a float and an int
            self._entry(*args)
        elif self._compiled:
            call(self._advance, *args)
        else:
            with compiling_notice():
                call(self._advance, *args)
            self._compiled = True
            self._entry = entry(self._advance, *args)
        # the same doubles numpy's (v - v0) / dt gave, as plain floats: cheaper to make and to read
        self._accel = ((st.item(_S_V) - v0x) / dt, (st.item(_S_V + 1) - v0z) / dt)

    # -- reading -----------------------------------------------------------------------------
    @property
    def t(self) -> float:
        return self.st.item(_S_T)

    @property
    def pitch_rate(self) -> float:
        """rad/s, nose up: :meth:`body`'s ``pitch_rate`` without building the whole state."""
        return self.st.item(_S_V + 2)

    def motion(self) -> tuple[float, float, float, float, float, float, float]:
        """:meth:`body`'s fields as a plain tuple (t, x, z, pitch, vx, vz, pitch_rate): for
        callers that read the body on every step, where building the dataclass costs more than
        reading the numbers."""
        s = self.st
        h = s[:_HEAD].tolist()
        return (s.item(_S_T), h[_S_Q], h[_S_Q + 1], h[_S_Q + 2], h[_S_V], h[_S_V + 1], h[_S_V + 2])

    def body(self) -> BodyState:
        return BodyState(*self.motion())

    def specific_force_body(self) -> tuple[float, float]:
        """What an accelerometer on the body reads over the last step (m/s^2), along body
        x (forward, +x when level) and body z (up): at rest level it reads (0, +g)."""
        ax, az = self._accel[0], self._accel[1] + self._gravity
        th = self.st.item(_S_Q + 2)
        c, s = math.cos(th), math.sin(th)
        return c * ax + s * az, -s * ax + c * az

    def leg_angles_deg(self) -> tuple[float, float]:
        """(uphill, downhill) leg angles below the body plane (deg)."""
        j = self.downhill
        return (math.degrees(self.st[k.S_Q + 4 - j]), math.degrees(self.st[k.S_Q + 3 + j]))

    def joint_angles_deg(self) -> tuple[float, float]:
        """(uphill, downhill) friction-joint angles (deg): the FSA's own position."""
        j = self.downhill
        return (math.degrees(self.st[k.S_QE + 1 - j]), math.degrees(self.st[k.S_QE + j]))

    def clearance(self) -> float:
        """Height of the lowest point above the surface (m); negative while pressed in."""
        return min(self._clearances())

    def in_contact(self) -> bool:
        """Whether any point presses on the surface. As numpy's ``max() > 0`` was, a NaN force
        reads as no contact; a list's max is cheaper than numpy's for these few points."""
        nf = self.st[_S_NF:_S_NF_END].tolist()
        return max(nf) > 0.0 and not any(f != f for f in nf)

    def thrust(self) -> tuple[float, float]:
        return float(self.st[k.S_THR]), float(self.st[k.S_THR + 1])

    def energy(self) -> dict[str, float]:
        out = np.zeros(len(ENERGY_TERMS))
        call(self._k.mechanical_energy, self._p, self._fl, self.ctx, self.st, self._ws, self._sx, out)
        return dict(zip(ENERGY_TERMS, out.tolist(), strict=True))

    def dissipated(self) -> dict[str, float]:
        d = [*self.st[k.S_DISS : k.S_DISS + len(DISSIPATION_TERMS) - 1].tolist(), float(self.st[k.S_DUSER])]
        return dict(zip(DISSIPATION_TERMS, d, strict=True))

    def _clearances(self) -> np.ndarray:
        M, f, pts, vel, J = k.kinematics_views(self._ws)
        k.kinematics(self._p, self.st, M, f, pts, vel, J)
        return pts[:, 0] * self.ctx[k.C_SIN] + pts[:, 1] * self.ctx[k.C_COS]
