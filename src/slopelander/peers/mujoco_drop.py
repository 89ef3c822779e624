"""The planar landing in MuJoCo: the peer a user would otherwise pick for sweeps.

The same vehicle as ``slopelander.model`` (bodies, inertias, geometry from the model's parameter
set), built as an MJCF model:

* the body on three planar joints (slide x, slide z, pitch hinge);
* per leg a **friction hinge** (the massless frame E of the paper's Fig. 5, given a small
  ``armature`` because MuJoCo needs inertia on every degree of freedom) carrying the planar
  friction torque as ``frictionloss``, with the **end stop** as its joint range, and in series
  a **flex hinge** with the leg's bending stiffness and damping;
* the feet (and, to detect touches, the leg joints and rotor hubs) as small spheres on a plane
  tilted by the slope, with friction coefficient mu_k;
* gravity; the rotors are left out (no thrust, so landings must have ``reverse_percent`` 0).

What MuJoCo cannot say as the model does, and how it is stood in for:

* **Contact stiffness.** MuJoCo's contact is a *mass-normalised* soft constraint, so the
  model's k_g, b_g in N/m cannot be given as such. The paper's ground is heavily over-damped
  (b_g/k_g = 20 ms, twelve times critical on a 10 g foot): no rebound, sub-millimetre sinking.
  The peer uses ``solref = (1 ms, 1)``: critically damped (no rebound), a time constant four
  timesteps long (MuJoCo advises at least two; at two the light feet chatter on and off the
  ground at rest), and a constant impedance ``impedance`` = 0.99. A foot then sinks at most
  0.35 mm in a 3 m/s level landing (0.18 mm at 1 m/s) and under a micrometre at rest; the
  model's ground sinks 0.35 mm under the vehicle's weight at rest.
* **Friction.** MuJoCo has one coefficient, so both static and kinetic are mu_k (the model is
  compared with ``matched_model``, which sets friction_static = friction_kinetic); friction is
  a soft constraint (elliptic cone, ``impratio`` makes it stiffer than the normal), so a foot
  or joint loaded below its limit still creeps slowly. The model's stiction does not.
* **End of travel.** A joint limit (a stop) instead of the model's 2-degree spring-damper zone;
  ``matched_model`` switches the zone off, so both stop at the same angle.
* Eq. 3 and 4 (the downhill joint's torque and foot friction growing with load and speed)
  have no MuJoCo element; ``matched_model`` switches them off.

A landing stops at rest by the model's own criterion (body slower than 2 cm/s and 2 deg/s,
every touching point and both joints stuck, for 0.15 s) or at the horizon; "stuck" in MuJoCo
means slower than ``stick_speed`` (a point along the surface) or ``stick_rate`` (a joint),
because soft friction never stops exactly. The outcome is classified by the model's own
classifier from the MuJoCo trajectory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slopelander.errors import SlopelanderError
from slopelander.model import kernel as k
from slopelander.model.conditions import LandingConditions, conditions_array
from slopelander.model.landing import LandingResult, Model, _validate_rows
from slopelander.model.outcome import RESULT_DTYPE, RESULT_FIELDS


class PeerError(SlopelanderError, RuntimeError):
    """The MuJoCo peer cannot run (MuJoCo missing) or cannot represent a request."""


def _mujoco():
    try:
        import mujoco
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise PeerError("the MuJoCo peer needs the 'mujoco' package: pip install 'slopelander[peers]'") from e
    return mujoco


def mujoco_available() -> bool:
    try:
        _mujoco()
    except PeerError:
        return False
    return True


MATCH_DROPPED = ("downhill_torque_growth", "downhill_friction_growth", "end_of_travel", "rotors")


def matched_model(model: Model | None = None) -> Model:
    """The model with only what the MuJoCo peer also has: no eq. 3/4, a plain end stop, no
    rotors, and one friction coefficient (static = kinetic)."""
    model = model or Model.default()
    m = model.without(*[e for e in MATCH_DROPPED if e in model.effects])
    m = m.without(*[e for e in ("rotor_reversal_delay",) if e in m.effects])
    return m.with_params(friction_static=model.params["friction_kinetic"])


def _check_expressible(model: Model) -> None:
    """Refuse a model whose physics the peer would silently leave out."""
    if model.rigid_gear or model.user_effects:
        raise PeerError("the MuJoCo peer has no rigid gear and no user effects")
    extra = [
        e
        for e in ("downhill_torque_growth", "downhill_friction_growth", "end_of_travel")
        if e in model.effects
    ]
    missing = [e for e in ("leg_flex", "foot_stiction") if e not in model.effects]
    P = model.params
    if extra or missing or P["friction_static"] != P["friction_kinetic"]:
        why = [f"has {', '.join(extra)}"] if extra else []
        why += [f"lacks {', '.join(missing)}"] if missing else []
        if P["friction_static"] != P["friction_kinetic"]:
            why.append("has friction_static != friction_kinetic")
        raise PeerError(
            f"the MuJoCo peer cannot express this model ({'; '.join(why)}): build it from "
            "matched_model(model)"
        )


@dataclass(frozen=True)
class PeerSettings:
    """MuJoCo's numerical choices (docs/reproduction.md says how they were chosen)."""

    timestep: float = 2.5e-4
    impedance: float = 0.99
    """solimp dmin = dmax of the contacts and the end stops."""
    joint_impedance: float = 0.9999
    """solimp dmin = dmax of the joints' friction (MuJoCo's upper bound: the least creep)."""
    impratio: float = 10.0
    """Friction-to-normal impedance ratio of the elliptic cone (> 1: less creep)."""
    armature: float = 1e-5
    """Inertia (kg*m^2) of each friction joint's frame; the model's frame is massless."""
    stick_speed: float = 2e-3
    """m/s: a touching point slower than this along the surface counts as stuck."""
    stick_rate: float = 0.02
    """rad/s: a friction joint slower than this counts as stuck."""
    timeconst: float = 1e-3
    """solref time constant (s) of every constraint; MuJoCo's advice is at least 2 timesteps,
    and at 2 the light feet chatter on and off the ground at rest."""
    noslip_iterations: int = 0
    """MuJoCo's no-slip post-pass (0 = off): removes the soft friction's slip, at a cost."""
    chunk: int = 200
    """Steps between checks of the stop criteria (every step is checked, in arrears)."""
    radius: float = 1e-4
    """Radius (m) of the contact spheres standing in for the model's contact points."""


def _xml(model: Model, s: PeerSettings) -> str:
    P = model.params
    nj = P["joints_per_planar_leg"]
    q_end = math.radians(P["leg_angle_max_deg"] - P["leg_travel_deg"])
    q_max = math.radians(P["leg_angle_max_deg"])
    L = P["leg_length"]
    tc = s.timeconst
    d = s.impedance
    imp = f"{d} {d} 0.001 0.5 2"
    dj = s.joint_impedance
    impj = f"{dj} {dj} 0.001 0.5 2"
    il = P["leg_inertia"]
    ib = P["body_inertia"]
    r = s.radius

    def leg(name: str, sgn: float, axis: str) -> str:
        return f"""
      <body name="e{name}" pos="{sgn * P["joint_x"]} 0 {-P["joint_z"]}">
        <inertial pos="0 0 0" mass="1e-9" diaginertia="1e-12 1e-12 1e-12"/>
        <joint name="f{name}" type="hinge" axis="{axis}" range="{q_end} {q_max}" limited="true"
               armature="{s.armature}" frictionloss="1" solreffriction="{tc} 1" solimpfriction="{impj}"
               solreflimit="{tc} 1" solimplimit="{imp}"/>
        <body name="l{name}">
          <inertial pos="{sgn * L / 2} 0 0" mass="{P["leg_mass"]}" diaginertia="{il} {il} {il}"/>
          <joint name="x{name}" type="hinge" axis="{axis}" stiffness="{P["flex_stiffness"] * nj}"
                 damping="{P["flex_damping"] * nj}"/>
          <geom name="foot{name}" type="sphere" size="{r}" pos="{sgn * L} 0 0"/>
        </body>
      </body>"""

    return f"""<mujoco model="slopelander planar drop">
  <compiler angle="radian"/>
  <option timestep="{s.timestep}" gravity="0 0 {-P["gravity"]}" integrator="implicitfast"
          cone="elliptic" impratio="{s.impratio}" noslip_iterations="{s.noslip_iterations}"/>
  <default>
    <geom contype="1" conaffinity="0" condim="3" friction="{P["friction_kinetic"]} 0 0"
          solref="{tc} 1" solimp="{imp}"/>
  </default>
  <worldbody>
    <body name="surface" mocap="true">
      <geom name="ground" type="plane" size="0 0 1" contype="0" conaffinity="1"/>
    </body>
    <body name="body">
      <inertial pos="0 0 0" mass="{P["body_mass"]}" diaginertia="{ib} {ib} {ib}"/>
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <joint name="pitch" type="hinge" axis="0 -1 0"/>
      <geom name="jointC" type="sphere" size="{r}" pos="{-P["joint_x"]} 0 {-P["joint_z"]}"/>
      <geom name="jointD" type="sphere" size="{r}" pos="{P["joint_x"]} 0 {-P["joint_z"]}"/>
      <geom name="rotor1" type="sphere" size="{r}" pos="{-P["rotor_arm"]} 0 0"/>
      <geom name="rotor2" type="sphere" size="{r}" pos="{P["rotor_arm"]} 0 0"/>
      {leg("C", -1.0, "0 -1 0")}
      {leg("D", 1.0, "0 1 0")}
    </body>
  </worldbody>
</mujoco>"""


class MujocoDrop:
    """The planar landing simulated by MuJoCo, with the model's initial state and outcomes."""

    def __init__(self, model: Model | None = None, settings: PeerSettings | None = None) -> None:
        mj = _mujoco()
        model = model or matched_model()
        _check_expressible(model)
        self.model = model
        self.settings = settings or PeerSettings()
        self._mj = mj
        self.mjmodel = mj.MjModel.from_xml_string(_xml(model, self.settings))
        self.data = mj.MjData(self.mjmodel)
        m = self.mjmodel
        self._fdof = [int(m.jnt_dofadr[mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, f"f{n}")]) for n in "CD"]
        P = model.params
        self._p = P.as_array()
        self._fl = model.flags()
        self._crit = model.criteria_array()
        self._L = P["leg_length"]
        self._jx = P["joint_x"]
        self._jz = P["joint_z"]
        self._rot = P["rotor_arm"]
        c = model.criteria
        self._horizon = c.horizon
        self._n_settle = round(c.settle_time / self.settings.timestep)

    # -- set-up ------------------------------------------------------------------------------
    def start(self, conditions: LandingConditions | np.ndarray) -> np.ndarray:
        """Put the MuJoCo vehicle in the model's initial state of a landing; return ``ctx``."""
        row = conditions_array([conditions]) if isinstance(conditions, LandingConditions) else conditions
        row = np.asarray(row).view(np.float64).reshape(-1)[: k.N_COND].copy()
        if row[k.K_REV] != 0.0:
            raise PeerError("the MuJoCo peer has no rotors: reverse_percent must be 0")
        st = np.zeros(k.N_STATE)
        ctx = np.zeros(k.N_CTX)
        k.init_landing(self._p, self._fl, row, st, ctx, k.make_workspace())
        self.place(ctx, st)
        return ctx

    def place(self, ctx: np.ndarray, st: np.ndarray) -> None:
        """Set slope, friction torques and the state from the model's ``ctx`` / state vector."""
        mj, m, d = self._mj, self.mjmodel, self.data
        a = math.atan2(ctx[k.C_SIN], ctx[k.C_COS])
        for j in range(2):
            m.dof_frictionloss[self._fdof[j]] = ctx[k.C_TAU + j]
        mj.mj_resetData(m, d)
        # the surface through the origin, its normal (sin a, cos a): a turn about +y
        d.mocap_quat[0] = [math.cos(a / 2), 0.0, math.sin(a / 2), 0.0]
        qe = st[k.S_QE : k.S_QE + 2]
        q = st[k.S_Q + 3 : k.S_Q + 5]
        lift = self.settings.radius / ctx[k.C_COS]  # the sphere's surface, not its centre, touches
        d.qpos[:] = [st[k.S_Q], st[k.S_Q + 1] + lift, st[k.S_Q + 2], qe[0], q[0] - qe[0], qe[1], q[1] - qe[1]]
        d.qvel[:] = [st[k.S_V], st[k.S_V + 1], st[k.S_V + 2], st[k.S_V + 3], 0.0, st[k.S_V + 4], 0.0]
        mj.mj_forward(m, d)

    # -- kinematics of the contact points, for many states at once ---------------------------
    def points(self, qpos: np.ndarray, qvel: np.ndarray, ctx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance to the surface and speed along it of the six contact points (feet C, D;
        joints C, D; rotors 1, 2), the model's order: two (n, 6) arrays."""
        x, z, th = qpos[:, 0], qpos[:, 1], qpos[:, 2]
        vx, vz, w = qvel[:, 0], qvel[:, 1], qvel[:, 2]
        c, s = np.cos(th), np.sin(th)
        L = self._L
        n = len(x)
        bx = np.empty((n, 6))
        bz = np.empty((n, 6))
        bxd = np.zeros((n, 6))
        bzd = np.zeros((n, 6))
        for j, sgn in ((0, -1.0), (1, 1.0)):
            q = qpos[:, 3 + 2 * j] + qpos[:, 4 + 2 * j]
            qd = qvel[:, 3 + 2 * j] + qvel[:, 4 + 2 * j]
            cq, sq = np.cos(q), np.sin(q)
            bx[:, j] = sgn * (self._jx + L * cq)
            bz[:, j] = -self._jz - L * sq
            bxd[:, j] = -sgn * L * sq * qd
            bzd[:, j] = -L * cq * qd
            bx[:, 2 + j] = sgn * self._jx
            bz[:, 2 + j] = -self._jz
            bx[:, 4 + j] = sgn * self._rot
            bz[:, 4 + j] = 0.0
        c2, s2, w2 = c[:, None], s[:, None], w[:, None]
        px = x[:, None] + c2 * bx - s2 * bz
        pz = z[:, None] + s2 * bx + c2 * bz
        pvx = vx[:, None] - w2 * (s2 * bx + c2 * bz) + c2 * bxd - s2 * bzd
        pvz = vz[:, None] + w2 * (c2 * bx - s2 * bz) + s2 * bxd + c2 * bzd
        sa, ca = ctx[k.C_SIN], ctx[k.C_COS]
        dist = sa * px + ca * pz - self.settings.radius
        slip = ca * pvx - sa * pvz
        return dist, slip

    # -- one landing -------------------------------------------------------------------------
    def land(self, conditions: LandingConditions, *, stop_at_rest: bool = True) -> LandingResult:
        """Simulate one landing; the outcome and numbers as the model reports them."""
        P = self.model.params
        conditions.validate(P.angle_min_deg, P.angle_max_deg)
        return LandingResult.from_row(self._run(self.start(conditions), stop_at_rest))

    def run_batch(
        self, conditions: list[LandingConditions] | np.ndarray, *, stop_at_rest: bool = True
    ) -> np.ndarray:
        """Outcomes of many landings one after another (one process, one core)."""
        arr = conditions_array(conditions)
        _validate_rows(arr, self.model)
        rows = arr.view(np.float64).reshape(len(arr), k.N_COND)
        out = np.zeros(len(arr), dtype=RESULT_DTYPE)
        for i in range(len(arr)):
            res = self._run(self.start(rows[i]), stop_at_rest)
            for f, name in enumerate(RESULT_FIELDS):
                out[name][i] = res[f]
        return out

    def _run(self, ctx: np.ndarray, stop_at_rest: bool) -> np.ndarray:
        mj, m, d, s = self._mj, self.mjmodel, self.data, self.settings
        crit = self._crit
        h = s.timestep
        K = s.chunk
        Q = np.empty((K, m.nq))
        V = np.empty((K, m.nv))
        x0, z0 = d.qpos[0], d.qpos[1]
        dsg = 1.0 if ctx[k.C_SIN] >= 0.0 else -1.0
        sa, ca = ctx[k.C_SIN], ctx[k.C_COS]
        qemin = np.array([d.qpos[3], d.qpos[5]])
        pmin = pmax = float(d.qpos[2])
        touch = False
        rest = 0
        flip_lim = math.radians(crit[k.R_FLIP])
        rate_lim = math.radians(crit[k.R_RATE])
        speed_lim = crit[k.R_SPEED]
        n_steps = round(self._horizon / h)
        done = 0
        final = None
        mj_step, qpos, qvel = mj.mj_step, d.qpos, d.qvel  # views into mjData, fetched once
        while done < n_steps:
            nk = min(K, n_steps - done)
            for i in range(nk):
                mj_step(m, d)
                Q[i] = qpos
                V[i] = qvel
            q, v = Q[:nk], V[:nk]
            dist, slip = self.points(q, v, ctx)
            on = dist < 0.0
            touch_i = np.logical_or.accumulate(on[:, 2:].any(axis=1)) | touch
            qe_c = np.minimum.accumulate(np.minimum(q[:, 3], qemin[0]))
            qe_d = np.minimum.accumulate(np.minimum(q[:, 5], qemin[1]))
            pmin_i = np.minimum.accumulate(np.minimum(q[:, 2], pmin))
            pmax_i = np.maximum.accumulate(np.maximum(q[:, 2], pmax))
            slide = dsg * (ca * (q[:, 0] - x0) - sa * (q[:, 1] - z0))
            at_rest = (
                (np.abs(v[:, 0]) <= speed_lim)
                & (np.abs(v[:, 1]) <= speed_lim)
                & (np.abs(v[:, 2]) <= rate_lim)
                & (np.abs(v[:, 3]) < s.stick_rate)
                & (np.abs(v[:, 5]) < s.stick_rate)
                & on.any(axis=1)
                & ~(on & (np.abs(slip) >= s.stick_speed)).any(axis=1)
            )
            idx = np.arange(nk)
            last_not = np.maximum.accumulate(np.where(at_rest, -1, idx))
            run = np.where(last_not >= 0, idx - last_not, rest + idx + 1)
            settled = run >= self._n_settle
            flip = np.maximum(-pmin_i, pmax_i) > flip_lim
            slid = np.abs(slide) > crit[k.R_SLIDE]
            over = (done + idx + 1) >= n_steps
            stop = settled | flip | slid | over
            if stop.any():
                i = int(np.argmax(stop))
                final = (i, bool(settled[i]), bool(slid[i]))
                break
            touch = bool(touch_i[-1])
            qemin[:] = qe_c[-1], qe_d[-1]
            pmin, pmax = float(pmin_i[-1]), float(pmax_i[-1])
            rest = int(run[-1])
            done += nk
        i, is_settled, is_slid = final
        st = np.zeros(k.N_STATE)
        st[k.S_QEMIN] = qe_c[i]
        st[k.S_QEMIN + 1] = qe_d[i]
        st[k.S_PMIN] = pmin_i[i]
        st[k.S_PMAX] = pmax_i[i]
        st[k.S_TOUCH] = 1.0 if touch_i[i] else 0.0
        st[k.S_Q + 2] = q[i, 2]
        st[k.S_T] = (done + i + 1) * h
        res = np.zeros(k.N_RESULT)
        k.classify(self._p, self._fl, ctx, st, crit, is_settled, is_slid, res)
        res[k.O_SLIDE] = slide[i]
        res[k.O_TSETTLE] = st[k.S_T] - run[i] * h if is_settled else np.nan
        if not stop_at_rest and is_settled:
            # run on to the horizon (for timing like for like); the outcome is frozen
            rest_steps = n_steps - (done + nk)  # the chunk itself already ran to its end
            if rest_steps > 0:
                mj.mj_step(m, d, nstep=rest_steps)
        return res

    # -- a vehicle standing on the slope ------------------------------------------------------
    def slide_at_rest(self, ctx: np.ndarray, st: np.ndarray, seconds: float) -> float:
        """Distance (m, + downhill) the body moves along the slope in ``seconds`` when started
        from the model's state ``st`` (e.g. a vehicle settled at rest) with zero velocity."""
        still = st.copy()
        still[k.S_V : k.S_V + 5] = 0.0
        self.place(ctx, still)
        d = self.data
        x0, z0 = d.qpos[0], d.qpos[1]
        self._mj.mj_step(self.mjmodel, d, nstep=round(seconds / self.settings.timestep))
        dsg = 1.0 if ctx[k.C_SIN] >= 0.0 else -1.0
        return dsg * (ctx[k.C_COS] * (d.qpos[0] - x0) - ctx[k.C_SIN] * (d.qpos[1] - z0))
