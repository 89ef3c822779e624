"""The compiled integrator: one step of the planar landing model, and a whole landing.

Why this shape (``docs/model.md`` has the full account):

* The feet are light (~10 g effective) on a stiff, heavily damped ground contact
  (k_g = 2.17e4 N/m, b_g = 437 N*s/m: twelve times critical). An explicit integrator would
  need steps of ~20 us. Instead each step is semi-implicit Euler with the contact
  spring-dampers, the foot's stiction spring and the Coulomb force (tied to the normal force)
  linearised implicitly: ``(M - h D - h^2 K) v' = M v + h f - h D v``, solved for the five
  generalised velocities. Contact modes (separated / stuck / slipping) are settled by a
  small active-set loop inside the step, so a foot that stops slipping sticks exactly.
* The friction joints' massless frames E, F (paper Fig. 5) are first-order: in each mode
  (stuck, slipping, slipping inside the end-of-travel zone) q_E obeys a linear ODE that is
  integrated exactly over the step, so the flex torque is exactly +-tau while slipping and
  the joint cannot creep while stuck.
* Everything is plain float arrays (parameters in ``PARAMETER_NAMES`` order, one flat
  state vector) so the same step serves the whole-landing function, the batch path and the
  1200 Hz stepper of the simulated vehicle. The step's scratch space is one record with named
  fields (``layout.WORKSPACE``), passed as a single pointer: a tuple of arrays cost a
  reference count per array per stage, a third of a landing's time.
* A step is a sequence of stages, each a small compiled function (:func:`_substep` lists
  them): forces at the start, the joints' law, the contacts with the feet's friction law, the
  implicit solve, the forces it applied, the integration. Where an effect has a law (the
  joint's torque, the foot's friction, the ground's normal force, extra forces, where a foot
  meets the ground, its memory's update after the step), the stage runs the built-in law and
  then the laws plugged into that seam, passed in as first-class compiled
  functions (the seam table, :mod:`slopelander.model.seams`): one compiled integrator serves
  every model with user effects and every candidate of a diagnosis, and a model without them
  runs its own compiled copy, in which no seam is looked at. User effects' memory lives at the
  end of the state vector (``S_MEM``); that copy neither saves nor restores it.
* The stages and small helpers are inlined by LLVM (``forceinline=True``: the ``alwaysinline``
  attribute), not in numba's own IR (``inline="always"``), which types each inlined body again
  at every call site: the same machine code within noise (the landings bit-identical), the first
  compile a third shorter (``benchmarks/first_compile.py``). Without either the stages stay calls,
  and a landing takes twice as long.

Coordinates: x downhill-positive horizontal, z up, angles counter-clockwise positive.
Q = (x, z, pitch, q_C, q_D); q_C is the left (-x) leg's angle below the body plane, q_D the
right (+x) leg's; both grow as the leg extends. The surface passes through the origin.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import overload

from slopelander.model import layout
from slopelander.model.layout import (  # noqa: F401 - re-exported: the layout's names
    C_BG,
    C_COS,
    C_DOWN,
    C_FEXT,
    C_JLOAD,
    C_KG,
    C_MEM,
    C_QINIT,
    C_SIN,
    C_TAU,
    D_EOT,
    D_FLEX,
    D_FOOT,
    D_GROUND,
    D_JOINT,
    D_ROTOR,
    DEG,
    F_EOT,
    F_FLEX,
    F_IMPLICIT_K,
    F_MU_GROWTH,
    F_PAPER_GROWTH,
    F_REGULARISED,
    F_REV_DELAY,
    F_RIGID,
    F_ROTORS,
    F_STICTION,
    F_STRIBECK,
    F_TAU_GROWTH,
    IMPACT_SPEED,
    MAX_ACTIVE_SET_ITERATIONS,
    MEMORY_ROW,
    N_CTX,
    N_FLAGS,
    N_FORCE_POINTS,
    N_POINTS,
    N_SEAMS,
    N_STATE,
    P_BE,
    P_BG,
    P_BQ,
    P_BR,
    P_BT,
    P_DELAY,
    P_DSTR,
    P_EZ,
    P_FMU,
    P_FTAU,
    P_G,
    P_IB,
    P_IL,
    P_JX,
    P_JZ,
    P_KE,
    P_KG,
    P_KQ,
    P_KR,
    P_KT,
    P_LL,
    P_MB,
    P_ML,
    P_MUK,
    P_MUS,
    P_NJ,
    P_QMAX,
    P_REV,
    P_RLIM,
    P_ROT,
    P_TAUM,
    P_TMAX,
    P_TRAVEL,
    P_VS,
    P_VSTR,
    PT_CENTRE,
    PT_FOOT,
    PT_JOINT,
    PT_ROTOR,
    REFINE,
    REFINE_WINDOW,
    S_ANC,
    S_CM,
    S_DIR,
    S_DISS,
    S_DUSER,
    S_FF,
    S_FT,
    S_JM,
    S_MEM,
    S_NF,
    S_NPEAK,
    S_PMAX,
    S_PMIN,
    S_Q,
    S_QE,
    S_QED,
    S_QEMIN,
    S_REFINE,
    S_REST,
    S_SLIP,
    S_T,
    S_THR,
    S_TIMP,
    S_TOUCH,
    S_V,
    S_W,
    S_WAIT,
    S_X0,
    SEAM_CONTACT_GEOMETRY,
    SEAM_FOOT_FRICTION,
    SEAM_FORCE,
    SEAM_JOINT_TORQUE,
    SEAM_NORMAL_FORCE,
    SEAM_POINT_FORCE,
    SEAM_ROW,
    SEAM_SLOTS,
    SEAM_UPDATE,
    STICK_SPEED,
    WORKSPACE,
)

layout.drop_stale_cache(__file__)


# --- seams --------------------------------------------------------------------------------
# Every jitted entry point takes the seam table ``sx``: None for a model without user effects,
# else ``(laws, slots, up)`` (see seams.py): per seam the compiled laws of the model's effects,
# how many are in use, and the slices of the user parameters ``up`` they read. Each stage runs
# the built-in law first, then the seam's laws in turn. The laws are first-class functions
# typed by their signature alone, so one compiled integrator serves every model with user
# effects and every candidate effect of a diagnosis.
#
# numba compiles the integrator once per kind of table. The helpers below are overloaded on
# it: for None they are constants (no law, the value given back), so the built-in model's
# step holds no call through a first-class function and reads no table; a model with user
# effects pays for its own calls. A table's slots are copied into the workspace record
# (``w.seams``, by _load_seams), where the step reads them without reference counts.


def _is_none(sx) -> bool:
    return isinstance(sx, types.NoneType)


def _load_seams(w, sx):
    """Copy the table's slots into the workspace record (compiled code only)."""
    raise NotImplementedError


@overload(_load_seams, jit_options={"cache": True})
def _load_seams_impl(w, sx):
    if _is_none(sx):
        return lambda w, sx: None

    def impl(w, sx):
        for i in range(N_SEAMS + 1):
            for j in range(SEAM_ROW):
                w.seams[i, j] = sx[1][i, j]

    return impl


def seam_laws(sx, w, seam):
    """How many laws ``seam`` holds in the table ``sx`` (compiled code only)."""
    raise NotImplementedError


@overload(seam_laws, jit_options={"cache": True})
def _seam_laws(sx, w, seam):
    if _is_none(sx):
        return lambda sx, w, seam: 0
    return lambda sx, w, seam: w.seams[seam, 0]


def has_normal_law(sx, w):
    """Whether a user's normal-force law replaces the built-in ground (compiled code only)."""
    raise NotImplementedError


@overload(has_normal_law, jit_options={"cache": True})
def _has_normal_law(sx, w):
    if _is_none(sx):
        return lambda sx, w: False
    return lambda sx, w: w.seams[SEAM_NORMAL_FORCE, 0] > 0


@njit(cache=True, forceinline=True)
def _params(sx, w, seam, k, ctx):
    """The user parameters the k-th law of a seam reads; its effect's memory is told in
    ``ctx[C_MEM]`` (what ``state.memory`` reads)."""
    ctx[C_MEM] = w.seams[seam, 3 + 3 * k]
    a = w.seams[seam, 1 + 3 * k]
    return sx[2][a : a + w.seams[seam, 2 + 3 * k]]


def saved_state(sx):
    """How much of the state a step that may be redone saves: the built-in model's part
    without user effects (their memory is never touched), the whole state with them."""
    raise NotImplementedError


@overload(saved_state, jit_options={"cache": True})
def _saved_state(sx):
    if _is_none(sx):
        return lambda sx: S_MEM
    return lambda sx: N_STATE


def has_contact_geometry(sx, w):
    """Whether a user's contact geometry moves the feet's contact points (compiled code only)."""
    raise NotImplementedError


@overload(has_contact_geometry, jit_options={"cache": True})
def _has_contact_geometry(sx, w):
    if _is_none(sx):
        return lambda sx, w: False
    return lambda sx, w: w.seams[SEAM_CONTACT_GEOMETRY, 0] > 0


def seam_contact_geometry(sx, w, t, st, ctx, leg, angle):
    """(reach, along) of the one contact geometry a model may set (compiled code only, and
    only where :func:`has_contact_geometry`)."""
    raise NotImplementedError


@overload(seam_contact_geometry, jit_options={"cache": True})
def _seam_contact_geometry(sx, w, t, st, ctx, leg, angle):
    if _is_none(sx):
        return lambda sx, w, t, st, ctx, leg, angle: (0.0, 0.0)

    def impl(sx, w, t, st, ctx, leg, angle):
        law = sx[0][SEAM_CONTACT_GEOMETRY][0]
        return law(t, st[:], ctx[:], _params(sx, w, SEAM_CONTACT_GEOMETRY, 0, ctx), leg, angle)

    return impl


def seam_update(sx, w, t, st, ctx, h):
    """Run the update seam's functions after a step (compiled code only)."""
    raise NotImplementedError


@overload(seam_update, jit_options={"cache": True})
def _seam_update(sx, w, t, st, ctx, h):
    if _is_none(sx):
        return lambda sx, w, t, st, ctx, h: None

    def impl(sx, w, t, st, ctx, h):
        laws = sx[0][SEAM_UPDATE]
        for k in range(SEAM_SLOTS):
            if k < w.seams[SEAM_UPDATE, 0]:
                laws[k](t, st[:], ctx[:], _params(sx, w, SEAM_UPDATE, k, ctx), h)

    return impl


def start_memory(sx, w, st):
    """Set the user effects' memory in ``st`` to its initial values (compiled code only)."""
    raise NotImplementedError


@overload(start_memory, jit_options={"cache": True})
def _start_memory(sx, w, st):
    if _is_none(sx):
        return lambda sx, w, st: None

    def impl(sx, w, st):
        a = w.seams[MEMORY_ROW, 1]
        for i in range(w.seams[MEMORY_ROW, 0]):
            st[S_MEM + i] = sx[2][a + i]

    return impl


def seam_force(sx, w, t, st, ctx, out):
    """Add the force seam's generalised forces to ``out`` (compiled code only)."""
    raise NotImplementedError


@overload(seam_force, jit_options={"cache": True})
def _seam_force(sx, w, t, st, ctx, out):
    if _is_none(sx):
        return lambda sx, w, t, st, ctx, out: None

    def impl(sx, w, t, st, ctx, out):
        laws = sx[0][SEAM_FORCE]
        for k in range(SEAM_SLOTS):
            if k < w.seams[SEAM_FORCE, 0]:
                laws[k](t, st[:], ctx[:], _params(sx, w, SEAM_FORCE, k, ctx), out[:])

    return impl


def seam_point_force(sx, w, t, st, ctx, out):
    """Add the point-force seam's forces at the named points to ``out`` (compiled code only)."""
    raise NotImplementedError


@overload(seam_point_force, jit_options={"cache": True})
def _seam_point_force(sx, w, t, st, ctx, out):
    if _is_none(sx):
        return lambda sx, w, t, st, ctx, out: None

    def impl(sx, w, t, st, ctx, out):
        laws = sx[0][SEAM_POINT_FORCE]
        for k in range(SEAM_SLOTS):
            if k < w.seams[SEAM_POINT_FORCE, 0]:
                laws[k](t, st[:], ctx[:], _params(sx, w, SEAM_POINT_FORCE, k, ctx), out)

    return impl


def seam_joint_torque(sx, w, t, st, ctx, leg, angle, rate, tau):
    """The slip torque after the joint-torque seam's laws (compiled code only)."""
    raise NotImplementedError


@overload(seam_joint_torque, jit_options={"cache": True})
def _seam_joint_torque(sx, w, t, st, ctx, leg, angle, rate, tau):
    if _is_none(sx):
        return lambda sx, w, t, st, ctx, leg, angle, rate, tau: tau

    def impl(sx, w, t, st, ctx, leg, angle, rate, tau):
        rigid, flex, _, _, q_zone, ke, _, kq, bq, _ = _joint_constants(w.p, w.fl)
        ctx[C_JLOAD] = _joint_load(st, w, leg, rigid, flex, q_zone, ke, kq, bq)
        laws = sx[0][SEAM_JOINT_TORQUE]
        for k in range(SEAM_SLOTS):
            if k < w.seams[SEAM_JOINT_TORQUE, 0]:
                up = _params(sx, w, SEAM_JOINT_TORQUE, k, ctx)
                tau = laws[k](t, st[:], ctx[:], up, leg, angle, rate, tau)
        return tau

    return impl


def seam_foot_friction(sx, w, t, st, ctx, leg, slip_speed, normal_force, mu):
    """The friction coefficient after the foot-friction seam's laws (compiled code only)."""
    raise NotImplementedError


@overload(seam_foot_friction, jit_options={"cache": True})
def _seam_foot_friction(sx, w, t, st, ctx, leg, slip_speed, normal_force, mu):
    if _is_none(sx):
        return lambda sx, w, t, st, ctx, leg, slip_speed, normal_force, mu: mu

    def impl(sx, w, t, st, ctx, leg, slip_speed, normal_force, mu):
        laws = sx[0][SEAM_FOOT_FRICTION]
        for k in range(SEAM_SLOTS):
            if k < w.seams[SEAM_FOOT_FRICTION, 0]:
                up = _params(sx, w, SEAM_FOOT_FRICTION, k, ctx)
                mu = laws[k](t, st[:], ctx[:], up, leg, slip_speed, normal_force, mu)
        return mu

    return impl


def seam_normal_force(sx, w, t, st, ctx, point, depth, rate):
    """(force, stiffness, damping) of the one normal law a model may set (check_user_effects
    allows one; compiled code only, and only where :func:`has_normal_law`)."""
    raise NotImplementedError


@overload(seam_normal_force, jit_options={"cache": True})
def _seam_normal_force(sx, w, t, st, ctx, point, depth, rate):
    if _is_none(sx):
        return lambda sx, w, t, st, ctx, point, depth, rate: (0.0, 0.0, 0.0)

    def impl(sx, w, t, st, ctx, point, depth, rate):
        law = sx[0][SEAM_NORMAL_FORCE][0]
        return law(t, st[:], ctx[:], _params(sx, w, SEAM_NORMAL_FORCE, 0, ctx), point, depth, rate)

    return impl


@njit(cache=True, forceinline=True)
def _rot(c, s, a, b):
    return c * a - s * b, s * a + c * b


@njit(cache=True, forceinline=True)
def _leg_geometry(p, j, q):
    """Joint position (body frame), leg unit vector u and du/dq for leg j at angle q."""
    sgn = -1.0 if j == 0 else 1.0
    hx = sgn * p[P_JX]
    hz = -p[P_JZ]
    ux = sgn * math.cos(q)
    uz = -math.sin(q)
    dux = -sgn * math.sin(q)
    duz = -math.cos(q)
    return hx, hz, ux, uz, dux, duz


@njit(cache=True, forceinline=True)
def _columns(i):
    """How many generalised coordinates move contact point i: x, z, pitch and a foot's own
    leg (the other columns of its Jacobian are zero)."""
    return 4 if i < 2 else 3


@njit(cache=True, forceinline=True)
def _column(i, b):
    """The b-th of them (b < _columns(i))."""
    return b if b < 3 else 3 + i


@njit(cache=True, forceinline=True)
def kinematics(p, st, M, f, pts, vel, J):
    """Mass matrix, velocity-product + gravity forces, and the contact points' kinematics.

    pts[i] / vel[i] are world position / velocity of point i, J[i] its 2x5 Jacobian; returns
    the cosine and sine of the pitch (later stages of the step reuse them). J's
    entries that are always zero (a foot's x row in z, the other leg's column, a point on
    the body in the legs' columns) are never written: ``J`` starts at zero (make_workspace).
    """
    th = st[S_Q + 2]
    c = math.cos(th)
    s = math.sin(th)
    w = st[S_V + 2]
    g = p[P_G]
    mb = p[P_MB]
    ml = p[P_ML]
    il = p[P_IL]
    L = p[P_LL]
    for a in range(5):
        f[a] = 0.0
        for b in range(5):
            M[a, b] = 0.0
    M[0, 0] = mb
    M[1, 1] = mb
    M[2, 2] = p[P_IB]
    f[1] = -mb * g

    # Legs: centre of mass (for M and forces) and foot (contact points 0, 1).
    for j in range(2):
        qi = 3 + j
        q = st[S_Q + qi]
        qd = st[S_V + qi]
        hx, hz, ux, uz, dux, duz = _leg_geometry(p, j, q)
        for k in range(2):
            ell = 0.5 * L if k == 0 else L
            rx = hx + ell * ux
            rz = hz + ell * uz
            wx, wz = _rot(c, s, rx, rz)  # R r
            srx, srz = _rot(c, s, -rz, rx)  # R S r
            dx, dz = _rot(c, s, ell * dux, ell * duz)  # R l u'
            sdx, sdz = _rot(c, s, -ell * duz, ell * dux)  # R S l u'
            # Jacobian columns: x, z, pitch, own leg angle
            jx0, jz0 = 1.0, 0.0
            jx1, jz1 = 0.0, 1.0
            jx2, jz2 = srx, srz
            jxq, jzq = dx, dz
            # velocity-product acceleration: -w^2 R r + 2 w qd R S l u' - qd^2 R l u
            bx = -w * w * wx + 2.0 * w * qd * sdx - qd * qd * ell * (c * ux - s * uz)
            bz = -w * w * wz + 2.0 * w * qd * sdz - qd * qd * ell * (s * ux + c * uz)
            if k == 0:
                cols_x = (jx0, jx1, jx2, jxq)
                cols_z = (jz0, jz1, jz2, jzq)
                idx = (0, 1, 2, qi)
                for a in range(4):
                    for b in range(4):
                        M[idx[a], idx[b]] += ml * (cols_x[a] * cols_x[b] + cols_z[a] * cols_z[b])
                    f[idx[a]] += -ml * (cols_x[a] * bx + cols_z[a] * bz) - ml * g * cols_z[a]
                # leg rotation: omega = pitch_rate + qd_C (left) or pitch_rate - qd_D (right)
                sg = 1.0 if j == 0 else -1.0
                M[2, 2] += il
                M[2, qi] += il * sg
                M[qi, 2] += il * sg
                M[qi, qi] += il
            else:
                pi_ = j
                pts[pi_, 0] = st[S_Q + 0] + wx
                pts[pi_, 1] = st[S_Q + 1] + wz
                J[pi_, 0, 0] = 1.0
                J[pi_, 1, 1] = 1.0
                J[pi_, 0, 2] = jx2
                J[pi_, 1, 2] = jz2
                J[pi_, 0, qi] = jxq
                J[pi_, 1, qi] = jzq
        # joint point (contact 2 + j), on the body
        wx, wz = _rot(c, s, hx, hz)
        srx, srz = _rot(c, s, -hz, hx)
        pts[2 + j, 0] = st[S_Q + 0] + wx
        pts[2 + j, 1] = st[S_Q + 1] + wz
        J[2 + j, 0, 0] = 1.0
        J[2 + j, 1, 1] = 1.0
        J[2 + j, 0, 2] = srx
        J[2 + j, 1, 2] = srz
    # rotor hubs (contact 4, 5), on the body
    for r in range(2):
        rx = -p[P_ROT] if r == 0 else p[P_ROT]
        wx, wz = _rot(c, s, rx, 0.0)
        srx, srz = _rot(c, s, 0.0, rx)
        pts[4 + r, 0] = st[S_Q + 0] + wx
        pts[4 + r, 1] = st[S_Q + 1] + wz
        J[4 + r, 0, 0] = 1.0
        J[4 + r, 1, 1] = 1.0
        J[4 + r, 0, 2] = srx
        J[4 + r, 1, 2] = srz
    for i in range(N_POINTS):
        for a in range(2):
            acc = 0.0
            for b in range(_columns(i)):
                acc += J[i, a, _column(i, b)] * st[S_V + _column(i, b)]
            vel[i, a] = acc
    return c, s


@njit(cache=True, forceinline=True)
def _solve5(A, b, x, n):
    """Gaussian elimination with partial pivoting (A, b are overwritten)."""
    for k in range(n):
        piv = k
        best = abs(A[k, k])
        for r in range(k + 1, n):
            if abs(A[r, k]) > best:
                best = abs(A[r, k])
                piv = r
        if piv != k:
            for cc in range(n):
                tmp = A[k, cc]
                A[k, cc] = A[piv, cc]
                A[piv, cc] = tmp
            tmp = b[k]
            b[k] = b[piv]
            b[piv] = tmp
        d = A[k, k]
        for r in range(k + 1, n):
            fct = A[r, k] / d
            if fct != 0.0:
                for cc in range(k + 1, n):  # (column k below the pivot is not read again)
                    A[r, cc] -= fct * A[k, cc]
                b[r] -= fct * b[k]
    for k in range(n - 1, -1, -1):
        acc = b[k]
        for cc in range(k + 1, n):
            acc -= A[k, cc] * x[cc]
        x[k] = acc / A[k, k]


@njit(cache=True, forceinline=True)
def _contact_rates(JNT, i, v):
    """Normal and tangential speed of contact point i for generalised velocities v."""
    ddn = 0.0
    sdn = 0.0
    for bb in range(_columns(i)):
        b = _column(i, bb)
        ddn += JNT[i, 0, b] * v[b]
        sdn += JNT[i, 1, b] * v[b]
    return ddn, sdn


@njit(cache=True)
def stribeck(mu_k, mu_s, slip_speed, v_s, delta):
    """Sliding friction coefficient of a foot slipping at ``slip_speed`` (velocity weakening):
    mu_k at speed, rising to mu_s as the slip stops, so the force is continuous at breakaway
    and a slowing foot can stick again below the static limit."""
    x = abs(slip_speed) / v_s
    e = x * x if delta == 2.0 else x**delta
    if e > 40.0 or mu_s <= mu_k:  # exp(-40) ~ 4e-18: mu_k to the last bit, without exp
        return mu_k
    return mu_k + (mu_s - mu_k) * math.exp(-e)


@njit(cache=True)
def _thrust(p, w):
    if w >= 0.0:
        return p[P_TMAX] * w * w
    return -p[P_TMAX] * p[P_REV] * w * w


def make_workspace():
    """The integrator's scratch workspace (:data:`~slopelander.model.layout.WORKSPACE`): a
    one-record array, allocated once per simulated vehicle or landing."""
    return np.zeros(1, dtype=WORKSPACE)


_make_workspace_jit = njit(cache=True)(make_workspace)


def kinematics_views(ws: np.ndarray) -> tuple[np.ndarray, ...]:
    """The arrays :func:`kinematics` fills, as views of a workspace: M, f, pts, vel, J."""
    return ws["M"][0], ws["f"][0], ws["pts"][0], ws["vel"][0], ws["J"][0]


@njit(cache=True)
def step(p, fl, ctx, st, h, u0, u1, ws, sx):
    """Advance the state ``st`` by ``h`` seconds with rotor commands u0, u1 in [-1, 1]."""
    advance(p, fl, ctx, st, h, 1, u0, u1, ws, sx)


@njit(cache=True)
def _load(w, p, fl, ctx, st):
    """Copy the model's arrays into the workspace record, where the step reads them."""
    for i in range(w.p.shape[0]):  # (the record's size: PARAMETER_NAMES)
        w.p[i] = p[i]
    for i in range(N_FLAGS):
        w.fl[i] = fl[i]
    for i in range(N_CTX):
        w.ctx[i] = ctx[i]
    for i in range(N_STATE):
        w.st[i] = st[i]


@njit(cache=True)
def _unload(w, ctx, st):
    """Copy the state and context the steps changed back out of the workspace record."""
    for i in range(N_CTX):
        ctx[i] = w.ctx[i]
    for i in range(N_STATE):
        st[i] = w.st[i]


@njit(cache=True)
def _step(w, h, u0, u1, sx):
    """:func:`step` on the workspace record ``w``, which holds the model's arrays (``_load``).

    A step in which a contact begins is redone as REFINE sub-steps, and so are the next
    REFINE_WINDOW - 1 steps: whether a foot sticks or slides at touchdown is decided within
    fractions of a millisecond, and deciding it on a coarse step biases the whole landing.
    """
    st = w.st
    if st[S_REFINE] > 0.0:
        st[S_REFINE] -= 1.0
        for _ in range(REFINE):
            _substep(w, h / REFINE, u0, u1, sx)
        return
    backup = w.backup
    # without user effects their memory is never touched: the built-in model's part is saved
    # (numba prunes the branch on the argument's None at compile time)
    if sx is None:  # noqa: SIM108
        n = S_MEM
    else:
        n = N_STATE
    for i in range(n):
        backup[i] = st[i]
    if _substep(w, h, u0, u1, sx) > 0:
        for i in range(n):
            st[i] = backup[i]
        st[S_REFINE] = REFINE_WINDOW - 1
        for _ in range(REFINE):
            _substep(w, h / REFINE, u0, u1, sx)


@njit(cache=True)
def _substep(w, h, u0, u1, sx):
    """One semi-implicit step; returns how many impacts (contacts beginning fast) it had.

    Stages, in order (each reads what the ones before left in the workspace record ``w``):
    forces at the start of the step, the joints' law, the contacts (with each foot's friction
    law), the implicit solve with its active set of contact modes, the forces that solve
    applied, and the integration of positions, friction joints and rotors. Every array is a
    field of ``w``: a field is passed on with no reference count (a plain array argument
    costs two atomic operations for each stage it passes through).
    """
    p, fl, ctx, st = w.p, w.fl, w.ctx, w.st
    w.pitch_cos, w.pitch_sin = kinematics(p, st, w.M, w.f, w.pts, w.vel, w.J)
    if sx is not None:  # noqa: SIM102 - (pruned at compile time without user effects)
        if has_contact_geometry(sx, w):
            contact_points(sx, w, p, st, ctx, h)
    user_forces = _applied_forces(p, fl, ctx, st, w, sx)
    _joint_law(p, fl, ctx, st, h, w, sx)
    began = _contacts(p, fl, ctx, st, w, sx)
    _solve(p, fl, st, h, w, sx)
    _contact_forces(p, fl, ctx, st, h, w, sx, user_forces)
    _integrate(p, fl, st, h, u0, u1, w)
    if sx is not None:
        seam_update(sx, w, st[S_T], st, ctx, h)
    return began


@njit(cache=True)
def contact_points(sx, w, p, st, ctx, h):
    """Move the feet's contact points (``pts``, ``vel``, ``J`` rows 0 and 1) from the legs'
    tips to where a user's contact geometry says each foot touches: ``reach`` beyond the tip
    toward the surface and ``along`` it. The point is carried by the leg (a point of a rigid
    pad), so its velocity and Jacobian gain the leg's rotation about the tip; every later
    stage (depth, slip, forces, energy) then sees the pad's point, not the tip.

    A pad that turns while stuck rolls: the point where it touches moves along the surface
    (by d along / d angle per radian) while the pad's material there does not slip (it moves
    by ``reach`` per radian about the tip), so a stuck foot's anchor moves by the difference
    over the step ``h`` (0: no step, the geometry alone)."""
    pts, vel, J = w.pts, w.vel, w.J
    nx, nz, tx, tz, _ = _surface(ctx)
    c, s = w.pitch_cos, w.pitch_sin
    t = st[S_T]
    for j in range(2):
        qi = 3 + j
        _, _, ux, uz, _, _ = _leg_geometry(p, j, st[S_Q + qi])
        uwx, uwz = _rot(c, s, ux, uz)
        angle = math.atan2(tx * uwx + tz * uwz, -(nx * uwx + nz * uwz))
        reach, along = seam_contact_geometry(sx, w, t, st, ctx, j, angle)
        rx = -reach * nx + along * tx
        rz = -reach * nz + along * tz
        sg = 1.0 if j == 0 else -1.0  # the leg's world rate: pitch rate + q_C', pitch rate - q_D'
        om = st[S_V + 2] + sg * st[S_V + qi]  # (= the rate of the contact angle)
        if h > 0.0 and st[S_CM + j] == 1.0 and om != 0.0:
            _, along2 = seam_contact_geometry(sx, w, t, st, ctx, j, angle + 1e-6)
            st[S_ANC + j] += h * om * ((along2 - along) / 1e-6 - reach)
        pts[j, 0] += rx
        pts[j, 1] += rz
        vel[j, 0] -= om * rz
        vel[j, 1] += om * rx
        J[j, 0, 2] -= rz
        J[j, 1, 2] += rx
        J[j, 0, qi] -= sg * rz
        J[j, 1, qi] += sg * rx


@njit(cache=True, forceinline=True)
def _surface(ctx):
    """Surface normal n (out of the ground), tangent t (toward +x) and the downhill sign
    along t (the slip speeds users read are downhill-positive)."""
    sa = ctx[C_SIN]
    ca = ctx[C_COS]
    return sa, ca, ca, -sa, 1.0 if sa >= 0.0 else -1.0


@njit(cache=True, forceinline=True)
def _joint_constants(p, fl):
    """(rigid, flex, q_end, q_max, q_zone, k_eot, b_eot, k_flex, b_flex, implicit springs)."""
    rigid = fl[F_RIGID] != 0
    flex = fl[F_FLEX] != 0 and not rigid
    q_end = (p[P_QMAX] - p[P_TRAVEL]) * DEG
    q_max = p[P_QMAX] * DEG
    q_zone = q_end + (p[P_EZ] * DEG if fl[F_EOT] != 0 else 0.0)
    ke = p[P_KE] if fl[F_EOT] != 0 else 0.0
    be = p[P_BE] if fl[F_EOT] != 0 else 0.0
    # a planar leg is a pair of real legs in parallel: torque, stiffness and damping add
    kq = p[P_KQ] * p[P_NJ]
    bq = p[P_BQ] * p[P_NJ]
    ik = 1.0 if fl[F_IMPLICIT_K] != 0 else 0.0
    return rigid, flex, q_end, q_max, q_zone, ke, be, kq, bq, ik


@njit(cache=True, forceinline=True)
def _applied_forces(p, fl, ctx, st, w, sx):
    """Stage 1: the explicit forces at the start of the step into ``f``: the force seams'
    (generalised and at named points), the external force on the body, rotor thrust.
    Returns whether any force seam is in use (its work is booked at the end)."""
    f, J, fx = w.f, w.J, w.f_user
    t = st[S_T]
    n_force = seam_laws(sx, w, SEAM_FORCE)
    n_point = seam_laws(sx, w, SEAM_POINT_FORCE)
    user_forces = n_force > 0 or n_point > 0
    if user_forces:
        for a in range(5):
            fx[a] = 0.0
        if n_force > 0:
            seam_force(sx, w, t, st, ctx, fx)
        if n_point > 0:
            pf = w.f_points[:].reshape((N_FORCE_POINTS, 2))
            for i in range(N_FORCE_POINTS):
                pf[i, 0] = 0.0
                pf[i, 1] = 0.0
            seam_point_force(sx, w, t, st, ctx, pf)
            for i in range(N_POINTS):
                for b in range(5):
                    fx[b] += J[i, 0, b] * pf[i, 0] + J[i, 1, b] * pf[i, 1]
            fx[0] += pf[PT_CENTRE, 0]
            fx[1] += pf[PT_CENTRE, 1]
        for a in range(5):
            f[a] += fx[a]
    for a in range(3):
        f[a] += ctx[C_FEXT + a]
    # rotors: thrust along body z at the hubs, from the speed at the start of the step
    bzx = -w.pitch_sin
    bzz = w.pitch_cos
    for rr in range(2):
        T = _thrust(p, st[S_W + rr]) if fl[F_ROTORS] != 0 else 0.0
        st[S_THR + rr] = T
        if T != 0.0:
            for b in range(3):  # (a hub moves with the body alone)
                f[b] += J[4 + rr, 0, b] * T * bzx + J[4 + rr, 1, b] * T * bzz
    return user_forces


@njit(cache=True, forceinline=True)
def _grows(flag, ctx, leg):
    """Whether eq. 3 or 4, switched on with ``flag`` (its effect's flag value), acts on this
    leg: 1, on either by its physical condition; 2 (``paper_downhill_growth``, set by
    Model.flags), on the downhill leg alone (level ground: either)."""
    return flag == 1 or leg == ctx[C_DOWN] or ctx[C_SIN] == 0.0


@njit(cache=True, forceinline=True)
def joint_torque_law(p, fl, ctx, st, leg, tau):
    """The built-in slip torque of a leg's friction joint: its preset, grown by eq. 3 on the
    leg whose foot is pushed outward (its friction points inward): on a slope the downhill
    leg, on level ground both; no switch at 0 deg (``paper_downhill_growth``: the downhill
    leg only)."""
    if fl[F_TAU_GROWTH] != 0 and _grows(fl[F_TAU_GROWTH], ctx, leg):
        tau *= 1.0 + p[P_FTAU] * max(0.0, (1.0 if leg == 0 else -1.0) * st[S_FT + leg])
    return tau


@njit(cache=True, forceinline=True)
def _joint_law(p, fl, ctx, st, h, w, sx):
    """Stage 2: each friction joint's slip torque (built-in law, then the joint-torque seam),
    and what the joints add to the step: the flex spring-damper or the slipping joint's
    torque into ``f``, their implicit parts into ``A0`` (= M + those); then r0 = M v + h f.

    Implicit terms go straight into A0 = M - h D - h^2 K; f keeps only the explicit part."""
    M, f, A0, r0 = w.M, w.f, w.A0, w.r0
    tau, zone, lam = w.tau, w.zone, w.lam
    t = st[S_T]
    rigid, flex, _, _, q_zone, ke, be, kq, bq, ik = _joint_constants(p, fl)
    n_torque = seam_laws(sx, w, SEAM_JOINT_TORQUE)
    for a in range(5):
        for b in range(5):
            A0[a, b] = M[a, b]
    for j in range(2):
        zone[j] = 0.0
        qi = 3 + j
        tj = joint_torque_law(p, fl, ctx, st, j, ctx[C_TAU + j])
        if n_torque > 0:
            # the leg's rate (a smooth state): the joint's own rate from the last step would
            # feed a speed-dependent law back into the joint's stick-slip switching; the law
            # may read the leg's load on the joint, from the last step's constraint torque
            tj = max(0.0, seam_joint_torque(sx, w, t, st, ctx, j, st[S_QE + j], st[S_V + qi], tj))
        lam[j] = 0.0
        tau[j] = tj
        if rigid:
            continue
        qE = st[S_QE + j]
        qc = st[S_Q + qi]
        vc = st[S_V + qi]
        m = st[S_JM + j]
        if flex:
            zj = 1.0 if qE < q_zone else 0.0
            zone[j] = zj
            if m == 0.0:
                # flex spring explicit (no numerical damping of the leg's bending mode);
                # its damper -b_q v_C implicit, carried by A0 alone
                f[qi] += kq * (qE - qc)
                A0[qi, qi] += h * bq
            else:
                B = bq + zj * be
                K = kq + zj * ke
                c0 = -tj * m + zj * ke * q_zone + kq * qc + bq * vc
                qEd = (c0 - K * qE) / B
                Tf = kq * (qE - qc) + bq * (qEd - vc)
                f[qi] += Tf
                dd = zj * be * bq / B
                A0[qi, qi] += h * dd
                f[qi] += dd * vc
        else:
            zj = 1.0 if qc < q_zone else 0.0
            zone[j] = zj
            if m != 0.0:
                f[qi] += -tj * m + zj * ke * (q_zone - qc)
                A0[qi, qi] += h * be * zj + h * h * ke * zj * ik
                # -b_e v is implicit: nothing explicit left
    for a in range(5):
        acc = 0.0
        for b in range(5):
            acc += M[a, b] * st[S_V + b]
        r0[a] = acc + h * f[a]


@njit(cache=True, forceinline=True)
def _joint_load(st, w, j, rigid, flex, q_zone, ke, kq, bq):
    """The torque leg j puts on its friction joint at the start of the step (planar N*m, +
    toward extension), for a joint-torque law (``state.joint_load``): with leg flex its
    spring-damper's, else while stuck the constraint torque of the last step, while slipping
    the torque it slips under; the end-of-travel spring's push included."""
    if rigid:
        return 0.0
    qE = st[S_QE + j]
    eot = ke * (q_zone - qE) if qE < q_zone else 0.0
    if flex:
        return kq * (st[S_Q + 3 + j] - qE) + bq * st[S_V + 3 + j] + eot
    m = st[S_JM + j]
    if m == 0.0:
        return -w.lam[j] + eot
    return m * w.tau[j]


@njit(cache=True, forceinline=True)
def _contacts(p, fl, ctx, st, w, sx):
    """Stage 3: every contact point's distance and speeds, its normal law at the start of the
    step (built-in spring-damper or the normal-force seam), which points are in contact and
    in what mode (a new contact slides if it arrives sliding), and each foot's friction
    coefficient (built-in law, then the foot-friction seam). Returns the impacts: contacts
    that began faster than IMPACT_SPEED."""
    pts, vel, J, JNT = w.pts, w.vel, w.J, w.JNT
    d0, dd0, s0, sd0, mu = w.dist, w.dist_rate, w.tang, w.tang_rate, w.mu
    nN, nk, nb, pad = w.law_force, w.law_stiffness, w.law_damping, w.pad_energy
    kgp, bgp, was_in, active = w.kg, w.bg, w.was_in, w.active
    t = st[S_T]
    nx, nz, tx, tz, dsg = _surface(ctx)
    rigid = fl[F_RIGID] != 0
    normal_law = has_normal_law(sx, w)
    friction_laws = seam_laws(sx, w, SEAM_FOOT_FRICTION) > 0
    began = 0
    # the rigid gear's feet are stiff plastic skids: a contact of their own that rebounds
    for i in range(N_POINTS):
        kgp[i] = p[P_KR] if rigid and i < 2 else p[P_KG]
        bgp[i] = p[P_BR] if rigid and i < 2 else p[P_BG]
    kt = p[P_KT]
    mus = p[P_MUS]
    stiction = fl[F_STICTION] != 0
    for i in range(N_POINTS):
        d0[i] = nx * pts[i, 0] + nz * pts[i, 1]
        dd0[i] = nx * vel[i, 0] + nz * vel[i, 1]
        s0[i] = tx * pts[i, 0] + tz * pts[i, 1]
        sd0[i] = tx * vel[i, 0] + tz * vel[i, 1]
        pad[i] = 0.0
        was_in[i] = 1 if st[S_CM + i] != 0.0 else 0
        if stiction and st[S_CM + i] == 1.0:
            pad[i] = 0.5 * kt * (s0[i] - st[S_ANC + i]) ** 2
        if normal_law:
            N0 = 0.0
            nN[i] = 0.0
            nk[i] = 0.0
            nb[i] = 0.0
            if d0[i] < 0.0:
                # the seam's law in penetration (into the ground) and its rate; it may read
                # the model's own ground at this point (a law scaling it reduces to it)
                ctx[C_KG] = kgp[i]
                ctx[C_BG] = bgp[i]
                N0, kk, bb = seam_normal_force(sx, w, t, st, ctx, i, -d0[i], -dd0[i])
                nN[i] = N0
                nk[i] = kk
                nb[i] = bb
        else:
            N0 = -kgp[i] * d0[i] - bgp[i] * dd0[i]
        active[i] = 0
        if d0[i] < 0.0 and N0 > 0.0:
            active[i] = 1
            for bb in range(_columns(i)):  # (the other columns stay zero)
                b = _column(i, bb)
                JNT[i, 0, b] = nx * J[i, 0, b] + nz * J[i, 1, b]
                JNT[i, 1, b] = tx * J[i, 0, b] + tz * J[i, 1, b]
            if st[S_CM + i] == 0.0:
                if dd0[i] < -IMPACT_SPEED:
                    began += 1
                # a foot arriving with tangential speed slides; it sticks once friction stops it
                if sd0[i] > STICK_SPEED:
                    st[S_CM + i] = 2.0
                elif sd0[i] < -STICK_SPEED:
                    st[S_CM + i] = 3.0
                else:
                    st[S_CM + i] = 1.0
                st[S_ANC + i] = s0[i]
        else:
            st[S_CM + i] = 0.0
        mu[i] = friction_coefficient(p, fl, ctx, tx, tz, vel, i, sd0[i], active[i] != 0, mus)
        if friction_laws and i < 2 and active[i]:
            mu[i] = max(0.0, seam_foot_friction(sx, w, t, st, ctx, i, dsg * sd0[i], max(N0, 0.0), mu[i]))
    return began


@njit(cache=True, forceinline=True)
def friction_coefficient(p, fl, ctx, tx, tz, vel, i, slip, touching, mu_s):
    """The built-in sliding friction coefficient of contact point i: mu_k; on a foot grown by
    eq. 4 with its leg's joint moving outward along the surface (downhill for the downhill
    leg, as the paper; it only raises friction; ``paper_downhill_growth``: the downhill leg
    only); then velocity weakening (Stribeck) while touching."""
    mu = p[P_MUK]
    if i < 2 and fl[F_MU_GROWTH] != 0 and _grows(fl[F_MU_GROWTH], ctx, i):
        vj = (-1.0 if i == 0 else 1.0) * (tx * vel[2 + i, 0] + tz * vel[2 + i, 1])
        mu *= max(1.0, 1.0 + p[P_FMU] * vj)
    if fl[F_STRIBECK] != 0 and touching:
        mu = stribeck(mu, mu_s, slip, p[P_VSTR], p[P_DSTR])
    return mu


@njit(cache=True, forceinline=True)
def _solve(p, fl, st, h, w, sx):
    """Stage 4: the implicit solve for the new velocities ``vn``, with the contacts' normal
    and friction forces linearised in it, repeated while a contact's mode changes (a point
    pulling on the ground lets go, a stuck foot whose force leaves the friction cone slides,
    a sliding foot that reverses sticks). Locked joints (rigid gear, a stuck joint without
    leg flex) keep their coordinate fixed. Returns the solves it took."""
    _lock_joints(fl, st, w)
    solves = 0
    for _ in range(MAX_ACTIVE_SET_ITERATIONS):
        solves += 1
        _assemble(p, fl, st, h, w, sx)
        _solve5(w.A, w.r, w.vn, 5)
        if not _modes_changed(p, fl, st, h, w, sx):
            break
    return solves


@njit(cache=True, forceinline=True)
def _lock_joints(fl, st, w):
    """Which generalised coordinates the solve holds fixed: the legs of the rigid gear, and
    without leg flex a leg whose joint is stuck."""
    locked = w.locked
    rigid = fl[F_RIGID] != 0
    flex = fl[F_FLEX] != 0 and not rigid
    for a in range(5):
        locked[a] = 0
    for j in range(2):
        if rigid or (not flex and st[S_JM + j] == 0.0):
            locked[3 + j] = 1


@njit(cache=True, forceinline=True)
def _assemble(p, fl, st, h, w, sx):
    """The system ``A vn = r`` of one active-set iteration: A0 and r0, each active contact's
    normal force and its friction in their present modes, the locked coordinates."""
    A, r, A0, r0 = w.A, w.r, w.A0, w.r0
    d0, dd0, s0, sd0, mu = w.dist, w.dist_rate, w.tang, w.tang_rate, w.mu
    nN, nk, nb, kgp, bgp = w.law_force, w.law_stiffness, w.law_damping, w.kg, w.bg
    ik = 1.0 if fl[F_IMPLICIT_K] != 0 else 0.0
    normal_law = has_normal_law(sx, w)
    kt = p[P_KT]
    bt = p[P_BT]
    stiction = fl[F_STICTION] != 0
    regular = fl[F_REGULARISED] != 0
    for a in range(5):
        r[a] = r0[a]
        for b in range(5):
            A[a, b] = A0[a, b]
    for i in range(N_POINTS):
        if not w.active[i]:
            continue
        if normal_law:
            # N(v') ~ N0 + b (rate' - rate0) + k h rate' (rate = -normal speed)
            nc0 = nN[i] + nb[i] * dd0[i]
            cn = h * h * nk[i] * ik + h * nb[i]
        else:
            nc0 = -kgp[i] * d0[i]
            cn = h * h * kgp[i] * ik + h * bgp[i]
        _add_rows(w, i, 0, 0, cn, h, nc0)
        mode = st[S_CM + i]
        if stiction:
            if mode == 1.0:  # stuck: the pad's spring-damper along the surface
                _add_rows(w, i, 1, 1, h * h * kt * ik + h * bt, h, -kt * (s0[i] - st[S_ANC + i]))
            else:  # sliding: mu times the normal force, against the slip
                sg = 1.0 if mode == 2.0 else -1.0
                rhs = -sg * mu[i] * nc0 if normal_law else sg * mu[i] * kgp[i] * d0[i]
                _add_rows(w, i, 1, 0, -sg * mu[i] * cn, h, rhs)
        elif regular:
            N0 = nN[i] if normal_law else -kgp[i] * d0[i] - bgp[i] * dd0[i]
            th_ = math.tanh(sd0[i] / p[P_VS])
            gg = mu[i] * N0 * (1.0 - th_ * th_) / p[P_VS]
            _add_rows(w, i, 1, 1, h * gg, h, -mu[i] * N0 * th_ + gg * sd0[i])
    for a in range(5):
        if w.locked[a]:
            for b in range(5):
                A[a, b] = 0.0
                A[b, a] = 0.0
            A[a, a] = 1.0
            r[a] = 0.0


@njit(cache=True, forceinline=True)
def _add_rows(w, i, row_a, row_b, coeff, h, rhs):
    """Add contact point i's force along its row ``row_a`` (0 normal, 1 tangent) to the
    system: ``h * rhs`` to r and ``coeff`` times its coupling to row ``row_b`` to A, over the
    columns that move the point."""
    A, r, JNT = w.A, w.r, w.JNT
    for aa in range(_columns(i)):
        a = _column(i, aa)
        ja = JNT[i, row_a, a]
        if ja != 0.0:
            r[a] += h * ja * rhs
            for bb in range(_columns(i)):
                b = _column(i, bb)
                A[a, b] += coeff * ja * JNT[i, row_b, b]


@njit(cache=True, forceinline=True)
def _modes_changed(p, fl, st, h, w, sx):
    """Settle each active contact's mode against the new velocities: a point pulling on the
    ground lets go, a stuck foot whose force leaves the friction cone slides, a sliding foot
    whose slip reverses sticks. Returns whether any changed (the system is solved again)."""
    d0, dd0, s0 = w.dist, w.dist_rate, w.tang
    nN, nk, nb, kgp, bgp = w.law_force, w.law_stiffness, w.law_damping, w.kg, w.bg
    active = w.active
    normal_law = has_normal_law(sx, w)
    kt = p[P_KT]
    bt = p[P_BT]
    mus = p[P_MUS]
    stiction = fl[F_STICTION] != 0
    changed = False
    for i in range(N_POINTS):
        if not active[i]:
            continue
        ddn, sdn = _contact_rates(w.JNT, i, w.vn)
        if normal_law:
            Nn = nN[i] + nb[i] * (dd0[i] - ddn) - h * nk[i] * ddn
        else:
            dn = d0[i] + h * ddn
            Nn = -kgp[i] * dn - bgp[i] * ddn
        if Nn < 0.0:
            active[i] = 0
            st[S_CM + i] = 0.0
            changed = True
            continue
        if not stiction:
            continue
        mode = st[S_CM + i]
        if mode == 1.0:
            ftn = -kt * (s0[i] + h * sdn - st[S_ANC + i]) - bt * sdn
            if abs(ftn) > mus * Nn:
                st[S_CM + i] = 2.0 if ftn < 0.0 else 3.0
                changed = True
        else:
            sg = 1.0 if mode == 2.0 else -1.0
            if sg * sdn < 0.0:
                st[S_CM + i] = 1.0
                st[S_ANC + i] = s0[i]
                changed = True
    return changed


@njit(cache=True, forceinline=True)
def _contact_forces(p, fl, ctx, st, h, w, sx, user_forces):
    """Stage 5: the forces the solve applied (outputs, the next step's laws, energy
    bookkeeping), every point's slip speed, the force seams' work, and the locked joints'
    constraint torques (a locked joint slips when its torque exceeds the preset)."""
    J, A0, r0, vn, fx, JNT = w.J, w.A0, w.r0, w.vn, w.f_user, w.JNT
    d0, dd0, s0, mu = w.dist, w.dist_rate, w.tang, w.mu
    nN, nk, nb, pad = w.law_force, w.law_stiffness, w.law_damping, w.pad_energy
    kgp, bgp, was_in = w.kg, w.bg, w.was_in
    active, locked, lam = w.active, w.locked, w.lam
    nx, nz, tx, tz, dsg = _surface(ctx)
    rigid = fl[F_RIGID] != 0
    flex = fl[F_FLEX] != 0 and not rigid
    normal_law = has_normal_law(sx, w)
    kt = p[P_KT]
    bt = p[P_BT]
    stiction = fl[F_STICTION] != 0
    regular = fl[F_REGULARISED] != 0
    for i in range(N_POINTS):
        st[S_NF + i] = 0.0
        st[S_FT + i] = 0.0
        if not active[i]:
            st[S_DISS + D_FOOT] += pad[i]  # lifted off stuck: the pad's spring lets go
            if was_in[i] and not normal_law:
                # let go still pressed in (a rebounding foot's force reaches zero first): the
                # massless contact's spring relaxes into its damper
                acc = 0.0
                for bb in range(_columns(i)):
                    b = _column(i, bb)
                    acc += (nx * J[i, 0, b] + nz * J[i, 1, b]) * vn[b]
                de = d0[i] + h * acc
                if de < 0.0:
                    st[S_DISS + D_GROUND] += 0.5 * kgp[i] * de * de
            continue
        ddn, sdn = _contact_rates(JNT, i, vn)
        if normal_law:
            Nn = nN[i] + nb[i] * (dd0[i] - ddn) - h * nk[i] * ddn
            # no potential is known for a user's law: its net work (stored + lost) is booked,
            # at the step's mean speed (what the kinetic energy's change sees)
            st[S_DISS + D_GROUND] -= Nn * 0.5 * (ddn + dd0[i]) * h
        else:
            Nn = -kgp[i] * (d0[i] + h * ddn) - bgp[i] * ddn
            st[S_DISS + D_GROUND] += bgp[i] * ddn * ddn * h
        if i < 2 and Nn > st[S_NPEAK]:
            st[S_NPEAK] = Nn
        if stiction:
            mode = st[S_CM + i]
            if mode == 1.0:
                ft = -kt * (s0[i] + h * sdn - st[S_ANC + i]) - bt * sdn
                st[S_DISS + D_FOOT] += bt * sdn * sdn * h
            else:
                # a stuck foot breaking away: what its pad spring held is lost with it
                st[S_DISS + D_FOOT] += pad[i]
                sg = 1.0 if mode == 2.0 else -1.0
                ft = -sg * mu[i] * Nn
                st[S_DISS + D_FOOT] += mu[i] * Nn * abs(sdn) * h
        elif regular:
            ft = -mu[i] * Nn * math.tanh(sdn / p[P_VS])
            st[S_DISS + D_FOOT] += -ft * sdn * h
        else:
            ft = 0.0
        st[S_NF + i] = Nn
        st[S_FT + i] = ft
    for j in range(2):
        st[S_FF + j] = abs(st[S_FT + j])
    # every point's speed along the surface (downhill-positive), for user laws next step
    for i in range(N_POINTS):
        acc = 0.0
        for bb in range(_columns(i)):
            b = _column(i, bb)
            acc += (tx * J[i, 0, b] + tz * J[i, 1, b]) * vn[b]
        st[S_SLIP + i] = dsg * acc
    if user_forces:
        for a in range(5):
            st[S_DUSER] -= fx[a] * vn[a] * h
    for i in range(2, N_POINTS):
        if active[i]:
            st[S_TOUCH] = 1.0

    # constraint torque of locked joints (needed to decide when a locked joint slips)
    if not flex and not rigid:
        for j in range(2):
            qi = 3 + j
            if locked[qi]:
                # rebuild the row of the unlocked system: A0 row + contact rows
                acc = -r0[qi]
                for b in range(5):
                    acc += A0[qi, b] * vn[b]
                for i in range(N_POINTS):
                    if active[i]:
                        acc -= h * (JNT[i, 0, qi] * st[S_NF + i] + JNT[i, 1, qi] * st[S_FT + i])
                lam[j] = acc / h


@njit(cache=True, forceinline=True)
def _integrate(p, fl, st, h, u0, u1, w):
    """Stage 6: the rotors' work, the new velocities and positions (semi-implicit Euler), the
    friction joints, the rotors' speeds, and the landing's bookkeeping."""
    vn = w.vn
    t = st[S_T]
    _rotor_work(st, h, w)
    qc_old0 = st[S_Q + 3]
    qc_old1 = st[S_Q + 4]
    for a in range(5):
        st[S_V + a] = vn[a]
        st[S_Q + a] += h * vn[a]
    qe_old0 = st[S_QE]
    qe_old1 = st[S_QE + 1]
    _friction_joints(p, fl, st, h, w, qc_old0, qc_old1)
    st[S_QED] = (st[S_QE] - qe_old0) / h
    st[S_QED + 1] = (st[S_QE + 1] - qe_old1) / h
    _rotor_speeds(p, fl, st, h, u0, u1)
    _bookkeeping(st, t, h, w.active)


@njit(cache=True, forceinline=True)
def _rotor_work(st, h, w):
    """The work the rotors' thrust did over the step (at the new velocities, the start pitch)."""
    J, vn = w.J, w.vn
    bzx = -w.pitch_sin  # the pitch at the start of the step, as the thrust was applied
    bzz = w.pitch_cos
    for rr in range(2):
        vz = bzx * (J[4 + rr, 0, 0] * vn[0] + J[4 + rr, 0, 2] * vn[2])
        vz += bzz * (J[4 + rr, 1, 1] * vn[1] + J[4 + rr, 1, 2] * vn[2])
        st[S_DISS + D_ROTOR] += st[S_THR + rr] * vz * h


@njit(cache=True, forceinline=True)
def _friction_joints(p, fl, st, h, w, qc_old0, qc_old1):
    """The friction joints' massless frames, updated exactly over the step in their mode
    (stuck, slipping, slipping in the end-of-travel zone), then their mode changes; without
    leg flex the joint is the leg and only its mode and limits change."""
    vn, tau, zone, lam = w.vn, w.tau, w.zone, w.lam
    rigid, flex, q_end, q_max, q_zone, ke, be, kq, bq, _ = _joint_constants(p, fl)
    for j in range(2):
        qi = 3 + j
        qc0 = qc_old0 if j == 0 else qc_old1
        qc1 = st[S_Q + qi]
        vc = vn[qi]
        tj = tau[j]
        if rigid:
            st[S_QE + j] = qc1
            continue
        if not flex:
            m = st[S_JM + j]
            st[S_QE + j] = qc1
            zj = zone[j]
            if m == 0.0:
                net = lam[j] - zj * ke * (q_zone - qc1)
                if net > tj and qc1 > q_end:
                    st[S_JM + j] = -1.0
                elif net < -tj and qc1 < q_max:
                    st[S_JM + j] = 1.0
            else:
                st[S_DISS + D_JOINT] += tj * abs(qc1 - qc0)
                st[S_DISS + D_EOT] += zj * be * vc * vc * h
                if m * vc <= 0.0:
                    st[S_JM + j] = 0.0
            if st[S_Q + qi] < q_end:
                st[S_Q + qi] = q_end
                st[S_V + qi] = 0.0
                st[S_JM + j] = 0.0
            elif st[S_Q + qi] > q_max:
                st[S_Q + qi] = q_max
                st[S_V + qi] = 0.0
                st[S_JM + j] = 0.0
            st[S_QE + j] = st[S_Q + qi]
            continue
        qE = st[S_QE + j]
        m = st[S_JM + j]
        zj = zone[j]
        if m == 0.0:
            Tst = kq * (qE - qc1) - bq * vc
            st[S_DISS + D_FLEX] += bq * vc * vc * h
            net = Tst - zj * ke * (q_zone - qE)
            if net > tj and qE > q_end:
                st[S_JM + j] = -1.0
            elif net < -tj and qE < q_max:
                st[S_JM + j] = 1.0
        else:
            B = bq + zj * be
            K = kq + zj * ke
            c0 = -tj * m + zj * ke * q_zone + kq * qc0 + bq * vc
            cs = kq * vc / K
            aa = (c0 - B * cs) / K
            e = math.exp(-K * h / B)
            qE1 = aa + cs * h + (qE - aa) * e
            qEd1 = cs - (K / B) * (qE - aa) * e
            # energy: joint friction on |dqE|, flex damper and EOT damper on the rates
            rel = 0.5 * ((cs - (K / B) * (qE - aa)) + qEd1) - vc
            st[S_DISS + D_JOINT] += tj * abs(qE1 - qE)
            st[S_DISS + D_FLEX] += bq * rel * rel * h
            st[S_DISS + D_EOT] += zj * be * qEd1 * qEd1 * h
            qE = qE1
            if m * qEd1 <= 0.0:
                st[S_JM + j] = 0.0
            if qE <= q_end:
                qE = q_end
                st[S_JM + j] = 0.0
            elif qE >= q_max:
                qE = q_max
                st[S_JM + j] = 0.0
            st[S_QE + j] = qE


@njit(cache=True, forceinline=True)
def _rotor_speeds(p, fl, st, h, u0, u1):
    """Rotors: a direction change waits out the reversal delay, the speed is first order."""
    if fl[F_ROTORS] == 0:
        st[S_W] = 0.0
        st[S_W + 1] = 0.0
        return
    e = -1.0  # the speed's decay over the step, once a rotor needs it
    for rr in range(2):
        u = u0 if rr == 0 else u1
        want = 1.0 if u > 0.0 else (-1.0 if u < 0.0 else 0.0)
        target = u
        if want != 0.0 and want != st[S_DIR + rr]:
            if fl[F_REV_DELAY] == 0:
                st[S_DIR + rr] = want
            else:
                if st[S_WAIT + rr] <= 0.0:
                    st[S_WAIT + rr] = p[P_DELAY]
                st[S_WAIT + rr] -= h
                target = 0.0
                if st[S_WAIT + rr] <= 0.0:
                    st[S_WAIT + rr] = 0.0
                    st[S_DIR + rr] = want
                    target = u
        else:
            st[S_WAIT + rr] = 0.0
        if st[S_W + rr] != target:  # at its target a rotor stays there
            if e < 0.0:
                e = math.exp(-h / p[P_TAUM])
            st[S_W + rr] = target + (st[S_W + rr] - target) * e


@njit(cache=True, forceinline=True)
def _bookkeeping(st, t, h, active):
    """Time, the first contact (time and place), the smallest joint angles, the pitch range."""
    st[S_T] = t + h
    if st[S_TIMP] < 0.0:
        for i in range(N_POINTS):
            if active[i]:
                st[S_TIMP] = t
                st[S_X0] = st[S_Q + 0]
                st[S_X0 + 1] = st[S_Q + 1]
                break
    for j in range(2):
        if st[S_QE + j] < st[S_QEMIN + j]:
            st[S_QEMIN + j] = st[S_QE + j]
    th = st[S_Q + 2]
    if th < st[S_PMIN]:
        st[S_PMIN] = th
    if th > st[S_PMAX]:
        st[S_PMAX] = th


# --- whole landings -------------------------------------------------------------------------
# conditions row (LandingConditions field order)
K_SLOPE, K_SPEED, K_VX, K_PITCH, K_RATE, K_TAU_UP, K_TAU_DOWN, K_Q_UP, K_Q_DOWN, K_REV, K_REVDLY = range(11)
K_REVDUR = 11  # s the reverse command is held (inf: to the horizon)
K_REVRAMP = 12  # s it then falls linearly to zero over (0: a step)
N_COND = 13
# criteria (OutcomeCriteria field order)
R_HORIZON, R_SLIDE, R_UNDER, R_FLIP, R_SPEED, R_RATE, R_SETTLE = range(7)
# result row (RESULT_FIELDS order)
O_CODE, O_CUP, O_CDOWN, O_SLIDE, O_PFINAL, O_PMIN, O_TSETTLE, O_TEND = range(8)
N_RESULT = 8


@njit(cache=True)
def init_landing(p, fl, cond, st, ctx, ws):
    """Fill ``st``/``ctx`` for a landing: lowest point just touching, impact velocity set."""
    a = cond[K_SLOPE] * DEG
    ctx[C_SIN] = math.sin(a)
    ctx[C_COS] = math.cos(a)
    down = 1 if a >= 0.0 else 0
    up = 1 - down
    ctx[C_DOWN] = down
    nj = p[P_NJ]
    ctx[C_TAU + up] = cond[K_TAU_UP] * nj
    ctx[C_TAU + down] = cond[K_TAU_DOWN] * nj
    for i in range(N_STATE):
        st[i] = 0.0
    qup = cond[K_Q_UP] * DEG
    qdown = cond[K_Q_DOWN] * DEG
    st[S_Q + 3 + up] = qup
    st[S_Q + 3 + down] = qdown
    st[S_QE + up] = qup
    st[S_QE + down] = qdown
    ctx[C_QINIT + up] = qup
    ctx[C_QINIT + down] = qdown
    st[S_Q + 2] = cond[K_PITCH] * DEG
    st[S_V + 0] = cond[K_VX]
    st[S_V + 1] = -cond[K_SPEED]
    st[S_V + 2] = cond[K_RATE] * DEG
    st[S_DIR] = 1.0
    st[S_DIR + 1] = 1.0
    st[S_TIMP] = -1.0
    w = ws[0]
    pts = w.pts
    kinematics(p, st, w.M, w.f, pts, w.vel, w.J)
    dmin = 1e300
    for i in range(N_POINTS):
        d = ctx[C_SIN] * pts[i, 0] + ctx[C_COS] * pts[i, 1]
        if d < dmin:
            dmin = d
    st[S_Q + 1] = -dmin / ctx[C_COS]
    st[S_QEMIN] = st[S_QE]
    st[S_QEMIN + 1] = st[S_QE + 1]
    st[S_PMIN] = st[S_Q + 2]
    st[S_PMAX] = st[S_Q + 2]


@njit(cache=True, forceinline=True)
def _start_user(sx, w, p, fl, ctx, st):
    """What user effects change at the start of a landing (``st`` just made by init_landing):
    their memory starts at its initial values, and with a contact geometry the vehicle is
    lifted until the lowest contact point just touches (the feet's pads, not their tips).

    The lift is the lowest point's height with the pads less its height with the tips (where
    init_landing put it, touching up to rounding): a geometry that reaches nowhere lifts by
    exactly 0, so at its neutral values a landing is the base model's to the last bit."""
    start_memory(sx, w, st)
    if has_contact_geometry(sx, w):
        w.pitch_cos, w.pitch_sin = kinematics(p, st, w.M, w.f, w.pts, w.vel, w.J)
        tips = _lowest(ctx, w.pts)
        contact_points(sx, w, p, st, ctx, 0.0)
        st[S_Q + 1] -= (_lowest(ctx, w.pts) - tips) / ctx[C_COS]


@njit(cache=True, forceinline=True)
def _lowest(ctx, pts):
    """The lowest of the contact points' heights above the surface (m)."""
    dmin = 1e300
    for i in range(N_POINTS):
        d = ctx[C_SIN] * pts[i, 0] + ctx[C_COS] * pts[i, 1]
        if d < dmin:
            dmin = d
    return dmin


@njit(cache=True)
def start_user_effects(p, fl, ctx, st, ws, sx):
    """:func:`_start_user` for a state made by :func:`init_landing` outside a landing run (the
    stepper's ``start_landing``)."""
    w = ws[0]
    _load_seams(w, sx)
    _start_user(sx, w, p, fl, ctx, st)


@njit(cache=True, forceinline=True)
def _at_rest(st, crit):
    if abs(st[S_V]) > crit[R_SPEED] or abs(st[S_V + 1]) > crit[R_SPEED]:
        return False
    if abs(st[S_V + 2]) > crit[R_RATE] * DEG:
        return False
    for j in range(2):
        if st[S_JM + j] != 0.0:
            return False
    touching = False
    for i in range(N_POINTS):
        cm = st[S_CM + i]
        if cm >= 2.0:
            return False
        if cm == 1.0:
            touching = True
    return touching


@njit(cache=True)
def classify(p, fl, ctx, st, crit, settled, slid, res):
    """Outcome of Sec. V-A from the bookkeeping in ``st`` (worst class reached wins)."""
    down = int(ctx[C_DOWN])
    up = 1 - down
    q_end = (p[P_QMAX] - p[P_TRAVEL]) * DEG
    q_eot = q_end + (p[P_EZ] * DEG if fl[F_EOT] != 0 else 1e-6)
    comp = np.zeros(2)
    eot = False
    rigid = fl[F_RIGID] != 0
    for j in range(2):
        span = ctx[C_QINIT + j] - q_end
        if not rigid and span > 0.0:
            comp[j] = (ctx[C_QINIT + j] - st[S_QEMIN + j]) / span
            if st[S_QEMIN + j] <= q_eot:
                eot = True
    flip = max(-st[S_PMIN], st[S_PMAX]) > crit[R_FLIP] * DEG
    if rigid and st[S_NPEAK] > p[P_RLIM]:
        code = 6  # the stock gear broke at impact: whatever followed, it needs repair
    elif flip:
        code = 5
    elif st[S_TOUCH] != 0.0:
        code = 4
    elif slid or not settled:
        code = 3
    elif eot:
        code = 2
    elif not rigid and max(comp[0], comp[1]) < crit[R_UNDER]:
        code = 1
    else:
        code = 0
    res[O_CODE] = code
    res[O_CUP] = comp[up]
    res[O_CDOWN] = comp[down]
    # pitches in the downhill frame (negative = toward downhill), so a mirrored slope
    # reports the same numbers
    if ctx[C_SIN] >= 0.0:
        res[O_PFINAL] = st[S_Q + 2] / DEG
        res[O_PMIN] = st[S_PMIN] / DEG
    else:
        res[O_PFINAL] = -st[S_Q + 2] / DEG
        res[O_PMIN] = -st[S_PMAX] / DEG
    res[O_TEND] = st[S_T] - max(st[S_TIMP], 0.0)


@njit(cache=True, forceinline=True)
def _slide(ctx, st):
    dsg = 1.0 if ctx[C_SIN] >= 0.0 else -1.0
    if st[S_TIMP] < 0.0:
        return 0.0
    return dsg * (ctx[C_COS] * (st[S_Q] - st[S_X0]) - ctx[C_SIN] * (st[S_Q + 1] - st[S_X0 + 1]))


@njit(cache=True, forceinline=True)
def reverse_command(cond, since):
    """Rotor command ``since`` s after first contact: 0 before the delay, full reverse held for
    the duration, then a linear ramp to zero (or a step), then 0."""
    full = -cond[K_REV] / 100.0
    if full == 0.0 or since < cond[K_REVDLY]:
        return 0.0
    held = since - cond[K_REVDLY]
    if held < cond[K_REVDUR]:
        return full
    ramp = cond[K_REVRAMP]
    if ramp <= 0.0:
        return 0.0
    left = 1.0 - (held - cond[K_REVDUR]) / ramp
    return full * left if left > 0.0 else 0.0


@njit(cache=True)
def thrust_off_time(cond):
    """Seconds after first contact when a reverse command that ends has reached zero; 0 if
    there is none or it is held (LandingConditions.thrust_off_time)."""
    if cond[K_REV] <= 0.0 or not math.isfinite(cond[K_REVDUR]):
        return 0.0
    return cond[K_REVDLY] + cond[K_REVDUR] + cond[K_REVRAMP]


@njit(cache=True)
def run_landing(p, fl, cond, h, crit, stop_at_settle, rec_every, rec, sx, res):
    """Simulate one landing from first contact; fill ``res``; return the samples recorded.

    ``rec`` (n x N_STATE) receives a copy of the state every ``rec_every`` steps (if
    rec_every > 0). The outcome is frozen the moment the vehicle settles, so a run that
    stops there and one that goes on to the horizon report the same result.
    """
    ws = _make_workspace_jit()
    return _run_landing(p, fl, cond, h, crit, stop_at_settle, rec_every, rec, sx, res, ws)


@njit(cache=True)
def _run_landing(p, fl, cond, h, crit, stop_at_settle, rec_every, rec, sx, res, ws):
    """:func:`run_landing` in a workspace its caller holds. The step works on the record
    ``ws[0]``, and a numba record does not keep its array alive: numba frees an array after
    its last use in a function, so a workspace allocated here and then used only through its
    record would be freed under the landing (garbage results once the memory was reused, seen
    on Dask workers). An argument lives as long as the caller's reference."""
    st0 = np.zeros(N_STATE)
    ctx0 = np.zeros(N_CTX)
    init_landing(p, fl, cond, st0, ctx0, ws)
    w = ws[0]
    _load_seams(w, sx)
    _start_user(sx, w, p, fl, ctx0, st0)
    _load(w, p, fl, ctx0, st0)
    st, ctx = w.st, w.ctx
    n_rec = 0
    if rec_every > 0 and rec.shape[0] > 0:
        for j in range(N_STATE):  # a loop, not a slice: numba's slice assignment compiles a
            rec[0, j] = st0[j]  # shape-mismatch message (string formatting: 2 s of the first run)
        n_rec = 1
    settled = False
    frozen = False
    slid = False
    t_off = thrust_off_time(cond)
    horizon = t_off + crit[R_HORIZON]
    k = 0
    res[O_TSETTLE] = np.nan
    res[O_SLIDE] = 0.0
    while True:
        t = st[S_T]
        u = 0.0
        if st[S_TIMP] >= 0.0:
            u = reverse_command(cond, t - st[S_TIMP])
        _step(w, h, u, u, sx)
        k += 1
        if rec_every > 0 and k % rec_every == 0 and n_rec < rec.shape[0]:
            for j in range(N_STATE):
                rec[n_rec, j] = st[j]
            n_rec += 1
        if frozen:
            if st[S_T] - max(st[S_TIMP], 0.0) >= horizon:
                break
            continue
        sl = _slide(ctx, st)
        if abs(sl) > crit[R_SLIDE]:
            slid = True
        if _at_rest(st, crit) and st[S_TIMP] >= 0.0 and st[S_T] - st[S_TIMP] >= t_off:
            st[S_REST] += h
        else:
            st[S_REST] = 0.0
        if st[S_REST] >= crit[R_SETTLE] and st[S_TIMP] >= 0.0:
            settled = True
        flip = max(-st[S_PMIN], st[S_PMAX]) > crit[R_FLIP] * DEG
        over = st[S_T] - max(st[S_TIMP], 0.0) >= horizon
        if settled or flip or slid or over:
            classify(p, fl, ctx, st, crit, settled, slid, res)
            res[O_SLIDE] = sl
            if settled:
                res[O_TSETTLE] = st[S_T] - st[S_TIMP] - st[S_REST]
            frozen = True
            # the outcome is decided; a recording of the whole horizon goes on after a settle
            # or a slide (a sliding vehicle keeps moving: cut short, a fit would compare
            # measured drops with a model frozen mid-slide), not after a flip
            if stop_at_settle or flip or over:
                break
    return n_rec


@njit(cache=True, nogil=True)
def run_batch(p, fl, conds, h, crit, stop_at_settle, sx, out):
    """Outcomes of many landings (rows of ``conds``). It releases the GIL: ``simulate_batch``
    runs chunks of a batch on several threads at once (a numba parallel loop cannot take the
    seam table's compiled functions)."""
    for i in range(conds.shape[0]):
        rec = np.zeros((0, N_STATE))
        run_landing(p, fl, conds[i], h, crit, stop_at_settle, 0, rec, sx, out[i])


@njit(cache=True)
def advance(p, fl, ctx, st, h, n, u0, u1, ws, sx):
    """``n`` steps of ``h`` with fixed rotor commands (one call per stepper tick)."""
    w = ws[0]
    _load(w, p, fl, ctx, st)
    _load_seams(w, sx)
    for _ in range(n):
        _step(w, h, u0, u1, sx)
    _unload(w, ctx, st)


@njit(cache=True)
def mechanical_energy(p, fl, ctx, st, ws, sx, out):
    """Kinetic, gravitational, ground-spring, stiction-spring, flex-spring and EOT-spring
    energy of the state (J), in that order."""
    w = ws[0]
    _load_seams(w, sx)
    M, pts = w.M, w.pts
    w.pitch_cos, w.pitch_sin = kinematics(p, st, M, w.f, pts, w.vel, w.J)
    if has_contact_geometry(sx, w):
        contact_points(sx, w, p, st, ctx, 0.0)
    normal_law = has_normal_law(sx, w)
    ke = 0.0
    for a in range(5):
        for b in range(5):
            ke += 0.5 * st[S_V + a] * M[a, b] * st[S_V + b]
    out[0] = ke
    # gravity: body at its centre, legs at their centres
    g = p[P_G]
    th = st[S_Q + 2]
    c = math.cos(th)
    s = math.sin(th)
    pe = p[P_MB] * g * st[S_Q + 1]
    for j in range(2):
        hx, hz, ux, uz, _, _ = _leg_geometry(p, j, st[S_Q + 3 + j])
        rx = hx + 0.5 * p[P_LL] * ux
        rz = hz + 0.5 * p[P_LL] * uz
        _, wz = _rot(c, s, rx, rz)
        pe += p[P_ML] * g * (st[S_Q + 1] + wz)
    out[1] = pe
    eg = 0.0
    es = 0.0
    for i in range(N_POINTS):
        d = ctx[C_SIN] * pts[i, 0] + ctx[C_COS] * pts[i, 1]
        # a point pressed in but let go holds no spring energy (booked as lost when it let go);
        # a user's law: booked as dissipated (ground)
        if d < 0.0 and st[S_CM + i] != 0.0 and not normal_law:
            kgi = p[P_KR] if fl[F_RIGID] != 0 and i < 2 else p[P_KG]
            eg += 0.5 * kgi * d * d
        if st[S_CM + i] == 1.0 and fl[F_STICTION] != 0:
            tang = ctx[C_COS] * pts[i, 0] - ctx[C_SIN] * pts[i, 1]
            es += 0.5 * p[P_KT] * (tang - st[S_ANC + i]) ** 2
    out[2] = eg
    out[3] = es
    ef = 0.0
    ee = 0.0
    rigid = fl[F_RIGID] != 0
    flex = fl[F_FLEX] != 0 and not rigid
    q_zone = (p[P_QMAX] - p[P_TRAVEL] + p[P_EZ]) * DEG
    for j in range(2):
        if flex:
            dq = st[S_QE + j] - st[S_Q + 3 + j]
            ef += 0.5 * p[P_KQ] * p[P_NJ] * dq * dq
        if fl[F_EOT] != 0 and not rigid and st[S_QE + j] < q_zone:
            ee += 0.5 * p[P_KE] * (q_zone - st[S_QE + j]) ** 2
    out[4] = ef
    out[5] = ee
