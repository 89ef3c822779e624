"""Where every number lives in the integrator's flat arrays, without numba.

The compiled integrator (:mod:`slopelander.model.kernel`) sees the model as plain float arrays:
parameters in :data:`~slopelander.model.parameters.PARAMETER_NAMES` order, effect switches,
a context (the surface and the leg settings) and one state vector, with a scratch workspace.
Their layouts, the named points a force can act at, and the built-in effects' declarations are
kept here so that a parameter file, an effect list or a user effect's declaration can be
checked without loading numba, and so that user code can name slots instead of counting them
(see :mod:`slopelander.model.state` for compiled accessors).

Coordinates: x downhill-positive horizontal, z up, angles counter-clockwise positive.
Q = (x, z, pitch, q_C, q_D); leg 0 is C (left, -x), leg 1 is D (right, +x).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slopelander.model.parameters import PARAMETER_NAMES

# --- parameter indices (PARAMETER_NAMES order) -------------------------------------------
_P = {n: i for i, n in enumerate(PARAMETER_NAMES)}
P_G = _P["gravity"]
P_MB = _P["body_mass"]
P_IB = _P["body_inertia"]
P_ROT = _P["rotor_arm"]
P_JX = _P["joint_x"]
P_JZ = _P["joint_z"]
P_ML = _P["leg_mass"]
P_IL = _P["leg_inertia"]
P_LL = _P["leg_length"]
P_QMAX = _P["leg_angle_max_deg"]
P_TRAVEL = _P["leg_travel_deg"]
P_NJ = _P["joints_per_planar_leg"]
P_KQ = _P["flex_stiffness"]
P_BQ = _P["flex_damping"]
P_EZ = _P["eot_zone_deg"]
P_KE = _P["eot_stiffness"]
P_BE = _P["eot_damping"]
P_FTAU = _P["factor_tau"]
P_FMU = _P["factor_mu"]
P_KG = _P["ground_stiffness"]
P_BG = _P["ground_damping"]
P_MUK = _P["friction_kinetic"]
P_MUS = _P["friction_static"]
P_KT = _P["stiction_stiffness"]
P_BT = _P["stiction_damping"]
P_VS = _P["friction_smoothing_speed"]
P_TMAX = _P["rotor_thrust_max"]
P_REV = _P["rotor_reverse_ratio"]
P_TAUM = _P["rotor_time_constant"]
P_DELAY = _P["rotor_reversal_delay"]
P_VSTR = _P["stribeck_speed"]
P_DSTR = _P["stribeck_exponent"]
P_KR = _P["rigid_contact_stiffness"]
P_BR = _P["rigid_contact_damping"]
P_RLIM = _P["rigid_load_limit"]

# --- effect switches ---------------------------------------------------------------------
F_FLEX = 0
F_EOT = 1
F_TAU_GROWTH = 2
F_MU_GROWTH = 3
F_STICTION = 4
F_REGULARISED = 5
F_ROTORS = 6
F_REV_DELAY = 7
F_RIGID = 8
F_IMPLICIT_K = 9  # solver setting, not an effect: springs implicit (stable) or explicit (symplectic)
F_STRIBECK = 10
F_PAPER_GROWTH = 11  # eqs. 3 and 4 on the downhill leg only (the paper's text), not by condition
N_FLAGS = 12

# --- context: the surface and the leg settings (may change between steps) ----------------
C_SIN = 0  # sin(slope)
C_COS = 1  # cos(slope)
C_DOWN = 2  # index of the downhill leg: 0 = C (left), 1 = D (right)
C_TAU = 3  # 3, 4: planar friction torque of leg C, D (N*m, already x joints_per_planar_leg)
C_QINIT = 5  # 5, 6: leg angle the compression is measured from (rad)
C_FEXT = 7  # 7, 8, 9: force on the body at its centre (N: world x, z; N*m: pitch), e.g. wind
C_KG = 10  # the ground's stiffness at the contact point a normal-force law is asked about (N/m)
C_BG = 11  # and its damping (N*s/m): set by the integrator just before it calls the law
C_MEM = 12  # where the called user effect's memory starts (offset from S_MEM): set before each call
C_JLOAD = 13  # the torque the leg puts on the friction joint a joint-torque law is asked about
#             (planar N*m, + toward extension), set just before it calls the law
N_CTX = 14

# --- state vector layout ------------------------------------------------------------------
S_Q = 0  # 0..4 generalised coordinates
S_V = 5  # 5..9 generalised velocities
S_QE = 10  # 10, 11 friction-joint angle of leg C, D (massless frames E, F)
S_JM = 12  # 12, 13 joint mode: 0 stuck, -1 slipping toward compression, +1 toward extension
S_CM = 14  # 14..19 contact mode per point: 0 off, 1 stuck, 2 slipping +t, 3 slipping -t
S_ANC = 20  # 20..25 stiction anchor (tangential coordinate) per point
S_W = 26  # 26, 27 rotor speed (fraction of full, signed)
S_DIR = 28  # 28, 29 rotor direction the ESC is set to (+1 / -1)
S_WAIT = 30  # 30, 31 remaining reversal dead time (s)
S_T = 32  # simulated time (s)
S_FF = 33  # 33, 34 foot friction force magnitude of leg C, D last step (N)
S_TIMP = 35  # time of first contact (s), -1 before
S_QEMIN = 36  # 36, 37 smallest friction-joint angle reached per leg
S_TOUCH = 38  # a joint or rotor has touched the surface (0/1)
S_PMIN = 39  # most negative pitch (rad)
S_PMAX = 40  # most positive pitch (rad)
S_X0 = 41  # 41, 42 centre-of-mass position at first contact
S_REST = 43  # time the rest condition has held continuously (s)
S_DISS = 44  # 44..49 energy dissipated: joint friction, flex damper, EOT damper,
#             ground damper, foot friction + stiction damper, and work done by the rotors
S_NF = 50  # 50..55 normal force per contact point (N), last step
S_FT = 56  # 56..61 tangential force per contact point (N), last step
S_THR = 62  # 62, 63 rotor thrust (N), last step
S_REFINE = 64  # macro-steps still to be taken as fine sub-steps after a touchdown
S_DUSER = 65  # energy taken out by user effects' forces (J): minus their work
S_SLIP = 66  # 66..71 speed along the surface per contact point, downhill-positive (m/s), last step
S_QED = 72  # 72, 73 friction-joint angular rate of leg C, D (rad/s), last step
S_NPEAK = 74  # largest normal force on either foot so far (N)
S_MEM = 75  # 75..82 user effects' memory (their declared states, all effects of a model in turn)
N_MEMORY = 8
N_STATE = 83

D_JOINT, D_FLEX, D_EOT, D_GROUND, D_FOOT, D_ROTOR = range(6)
N_POINTS = 6  # contact points: feet C, D; joints C, D; rotor hubs 1, 2

# --- named points a user force can act at (rows of the point-force array) ----------------
PT_FOOT = 0  # 0, 1: foot of leg C, D
PT_JOINT = 2  # 2, 3: leg joint C, D (on the body)
PT_ROTOR = 4  # 4, 5: rotor hub 1 (-x), 2 (+x)
PT_CENTRE = 6  # the body's centre of mass
N_FORCE_POINTS = 7
LEG_C = 0
LEG_D = 1

# --- solver settings ----------------------------------------------------------------------
MAX_ACTIVE_SET_ITERATIONS = 6
REFINE = 16  # a step in which a contact begins is redone as this many sub-steps...
REFINE_WINDOW = 4  # ...and so are the next few: impacts settle within ~1 ms
IMPACT_SPEED = 0.1  # m/s: a contact beginning faster than this is an impact (grazing is not)
STICK_SPEED = 1e-3  # m/s: a contact arriving slower than this along the surface starts stuck

DEG = math.pi / 180.0


# --- built-in effects -----------------------------------------------------------------------
@dataclass(frozen=True)
class Effect:
    name: str
    description: str
    parameters: tuple[str, ...]
    flag: int


BUILTIN_EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "leg_flex",
            "legs bend on a torsional spring-damper in series with the friction joint (eq. 2)",
            ("flex_stiffness", "flex_damping"),
            F_FLEX,
        ),
        Effect(
            "end_of_travel",
            "spring-damper stop within eot_zone_deg of the joint limit",
            ("eot_zone_deg", "eot_stiffness", "eot_damping"),
            F_EOT,
        ),
        Effect(
            "downhill_torque_growth",
            "a joint's torque grows with its foot's inward friction (eq. 3; on a slope the downhill leg)",
            ("factor_tau",),
            F_TAU_GROWTH,
        ),
        Effect(
            "downhill_friction_growth",
            "a foot's friction grows with its joint's outward speed (eq. 4; on a slope the downhill leg)",
            ("factor_mu",),
            F_MU_GROWTH,
        ),
        Effect(
            "paper_downhill_growth",
            "eqs. 3 and 4 on the downhill leg only, as the paper's text reads (level ground: both "
            "legs by their condition); without it each leg grows by its physical condition",
            (),
            F_PAPER_GROWTH,
        ),
        Effect(
            "foot_stiction",
            "feet stick (tangential spring-damper) until |F_t| > mu_s N, then slide with mu_k",
            ("friction_static", "stiction_stiffness", "stiction_damping"),
            F_STICTION,
        ),
        Effect(
            "regularised_friction",
            "feet follow mu_k N tanh(v / v_s): smooth, but creeps on slopes (comparison only)",
            ("friction_smoothing_speed",),
            F_REGULARISED,
        ),
        Effect(
            "velocity_weakening_friction",
            "a sliding foot's friction rises from mu_k toward mu_s as it slows (Stribeck), so a "
            "slowing foot can stick again below the static limit",
            ("stribeck_speed", "stribeck_exponent"),
            F_STRIBECK,
        ),
        Effect(
            "rotors",
            "rotor thrust with first-order speed dynamics, weaker in reverse",
            ("rotor_thrust_max", "rotor_reverse_ratio", "rotor_time_constant"),
            F_ROTORS,
        ),
        Effect(
            "rotor_reversal_delay",
            "a rotor changing direction stops and restarts: no thrust for the delay",
            ("rotor_reversal_delay",),
            F_REV_DELAY,
        ),
        Effect(
            "rigid_gear",
            "stock rigid landing gear: joints locked at their set angle, same geometry, its feet "
            "on a stiff, rebounding skid contact; a foot load over rigid_load_limit damages it",
            ("rigid_contact_stiffness", "rigid_contact_damping", "rigid_load_limit"),
            F_RIGID,
        ),
    )
}

# --- user-effect seams: where a user's compiled function enters the integrator ------------
SEAMS: dict[str, str] = {
    "force": "force(t, st, ctx, up, out): add generalised forces on (x, z, pitch, q_C, q_D) to out",
    "point_force": "point_force(t, st, ctx, up, out): add world (x, z) forces at the named points "
    "(rows PT_FOOT.., PT_JOINT.., PT_ROTOR.., PT_CENTRE) to out",
    "joint_torque": "joint_torque(t, st, ctx, up, leg, angle, rate, tau) -> slip torque of the "
    "leg's friction joint (planar, N*m); angle is the joint's, rate the leg's; tau is the built-in value",
    "foot_friction": "foot_friction(t, st, ctx, up, leg, slip_speed, normal_force, mu) -> sliding "
    "friction coefficient of the leg's foot; mu is the built-in value",
    "normal_force": "normal_force(t, st, ctx, up, point, depth, rate) -> (force, stiffness, "
    "damping): the contact's normal force law and its derivatives",
    "contact_geometry": "contact_geometry(t, st, ctx, up, leg, angle) -> (reach, along): where the "
    "foot touches: reach (m) beyond the leg's tip toward the surface, along (m) the surface "
    "(+x side), for the leg at angle (rad) from the surface's inward normal",
    "update": "update(t, st, ctx, up, h): once per step after it, update the effect's memory "
    "(state.memory / state.set_memory)",
}


SEAM_INDEX: dict[str, int] = {name: i for i, name in enumerate(SEAMS)}
SEAM_SLOTS = 4  # laws one seam can take in one model
(
    SEAM_FORCE,
    SEAM_POINT_FORCE,
    SEAM_JOINT_TORQUE,
    SEAM_FOOT_FRICTION,
    SEAM_NORMAL_FORCE,
    SEAM_CONTACT_GEOMETRY,
    SEAM_UPDATE,
) = range(7)
N_SEAMS = len(SEAMS)
# a seam table's slots: one row per seam, [laws in use, then per law: the offset and count of
# its parameters in ``up``, the offset of its effect's memory in the state (from S_MEM)]; one
# more row, MEMORY_ROW, holds [memory slots in use, offset of their initial values in ``up``]
SEAM_ROW = 1 + 3 * SEAM_SLOTS
MEMORY_ROW = N_SEAMS


# --- the integrator's scratch workspace ---------------------------------------------------
# One record (numpy structured dtype): compiled code reads its fields by name (``w.M[a, b]``)
# and passes the record on as a single pointer; its fields are arrays without reference counts,
# which a step would otherwise update twice per array per stage (a third of a landing's time).
WORKSPACE = np.dtype(
    [
        # the model's arrays, copied in for the steps (see kernel._load)
        ("p", np.float64, len(PARAMETER_NAMES)),  # parameters
        ("fl", np.int64, N_FLAGS),  # effect switches
        ("ctx", np.float64, N_CTX),  # context
        # (the pads keep st and the step's arrays after the seam table at the offsets within a
        # cache line they had before the state and the table grew)
        ("pad_st", np.float64, 5),
        ("st", np.float64, N_STATE),  # state
        ("seams", np.int64, (N_SEAMS + 1, SEAM_ROW)),  # a seam table's slots (seams.py)
        ("pad_step", np.float64, 5),
        # kinematics at the start of the step
        ("pitch_cos", np.float64),  # cosine of the pitch
        ("pitch_sin", np.float64),  # and its sine
        ("M", np.float64, (5, 5)),  # mass matrix
        ("f", np.float64, 5),  # explicit generalised forces: velocity products, gravity, applied
        ("pts", np.float64, (N_POINTS, 2)),  # world position of each contact point
        ("vel", np.float64, (N_POINTS, 2)),  # its world velocity
        ("J", np.float64, (N_POINTS, 2, 5)),  # its 2x5 Jacobian (world x, z rows)
        # the implicit solve: (M - h D - h^2 K) v' = M v + h f
        ("A0", np.float64, (5, 5)),  # matrix before the contacts: M and the joints' implicit parts
        ("r0", np.float64, 5),  # right-hand side before the contacts: M v + h f
        ("A", np.float64, (5, 5)),  # the matrix of one active-set iteration (overwritten by the solve)
        ("r", np.float64, 5),  # its right-hand side
        ("vn", np.float64, 5),  # the new generalised velocities
        ("JNT", np.float64, (N_POINTS, 2, 5)),  # per point: its Jacobian along the normal and tangent
        ("f_user", np.float64, 5),  # generalised force of the force seams this step
        ("f_points", np.float64, N_FORCE_POINTS * 2),  # the point-force seam's (x, z) per named point
        ("backup", np.float64, N_STATE),  # the state before the step (to redo a touchdown finely)
        # per contact point, at the start of the step
        ("dist", np.float64, N_POINTS),  # distance from the surface (+ out of it)
        ("dist_rate", np.float64, N_POINTS),  # its rate
        ("tang", np.float64, N_POINTS),  # position along the surface tangent
        ("tang_rate", np.float64, N_POINTS),  # its rate
        ("mu", np.float64, N_POINTS),  # sliding friction coefficient
        ("law_force", np.float64, N_POINTS),  # a normal-force seam's force,
        ("law_stiffness", np.float64, N_POINTS),  # its stiffness
        ("law_damping", np.float64, N_POINTS),  # and its damping
        ("pad_energy", np.float64, N_POINTS),  # energy in a stuck foot's stiction spring
        ("kg", np.float64, N_POINTS),  # the built-in ground's stiffness (the rigid gear's feet differ)
        ("bg", np.float64, N_POINTS),  # and damping
        ("was_in", np.uint8, N_POINTS),  # in contact at the start of the step
        ("active", np.uint8, N_POINTS),  # in contact this step (the active set)
        ("locked", np.uint8, 5),  # generalised coordinate held fixed this step
        # per friction joint
        ("tau", np.float64, 2),  # slip torque (planar, N*m)
        ("zone", np.float64, 2),  # 1 inside the end-of-travel zone
        ("lam", np.float64, 2),  # constraint torque of a locked joint
    ],
    align=True,
)


def layout_digest() -> str:
    """Hash of the files that fix the array layouts: a compiled integrator built against
    other layouts must not be reused (numba's cache only watches the function's own file)."""
    here = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for name in ("layout.py", "parameters.py"):
        h.update((here / name).read_bytes())
    return h.hexdigest()[:20]


def drop_stale_cache(module_file: str) -> None:
    """Delete a compiled module's numba cache files if the layouts changed since they were
    written (numba keys them on that module's own source only). Never raises: a cache that
    cannot be written is recompiled, as numba does."""
    path = Path(module_file).resolve()
    cache = path.parent / "__pycache__"
    stamp = cache / f"{path.stem}.layout"
    digest = layout_digest()
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    try:
        for f in cache.glob(f"{path.stem}.*.nb[ic]"):
            f.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        stamp.write_text(digest)
    except OSError:
        pass
