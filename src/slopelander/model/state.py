"""Named, compiled accessors of the integrator's state and context, for user effects.

A user effect reads the state ``st`` and the context ``ctx`` it is handed; these small
``numba.njit`` functions name the slots (laid out in :mod:`slopelander.model.layout`) so that
a user's file says ``state.pitch_rate(st)`` rather than ``st[7]``, and keeps working if the
layout grows. They compile into the caller: calling them costs nothing.

Legs: 0 is C (left, -x), 1 is D (right, +x); ``state.downhill_leg(ctx)`` says which is
downhill. Contact points: feet 0, 1; joints 2, 3; rotor hubs 4, 5. Values "last step" are
those of the step before the current one (what the integrator knew when the step began).
"""

from __future__ import annotations

from numba import njit

from slopelander.model import layout as lay

lay.drop_stale_cache(__file__)  # these read the layout's constants: recompile when it changes


@njit(cache=True)
def time(st):
    """Simulated time (s)."""
    return st[lay.S_T]


@njit(cache=True)
def x(st):
    """Centre-of-mass horizontal position (m, downhill-positive)."""
    return st[lay.S_Q]


@njit(cache=True)
def z(st):
    """Centre-of-mass height (m)."""
    return st[lay.S_Q + 1]


@njit(cache=True)
def pitch(st):
    """Body pitch (rad, counter-clockwise positive)."""
    return st[lay.S_Q + 2]


@njit(cache=True)
def vx(st):
    return st[lay.S_V]


@njit(cache=True)
def vz(st):
    return st[lay.S_V + 1]


@njit(cache=True)
def pitch_rate(st):
    """Body pitch rate (rad/s)."""
    return st[lay.S_V + 2]


@njit(cache=True)
def leg_angle(st, leg):
    """Leg angle below the body plane (rad); grows as the leg extends."""
    return st[lay.S_Q + 3 + leg]


@njit(cache=True)
def leg_rate(st, leg):
    """Leg angular rate (rad/s); negative while the leg compresses."""
    return st[lay.S_V + 3 + leg]


@njit(cache=True)
def joint_angle(st, leg):
    """Friction-joint angle (rad): the shock absorber's own position (the leg bends about it)."""
    return st[lay.S_QE + leg]


@njit(cache=True)
def joint_rate(st, leg):
    """Friction-joint angular rate over the last step (rad/s); negative while compressing."""
    return st[lay.S_QED + leg]


@njit(cache=True)
def joint_slipping(st, leg):
    """0 while the friction joint holds, -1 slipping toward compression, +1 toward extension."""
    return st[lay.S_JM + leg]


@njit(cache=True)
def in_contact(st, point):
    """True if contact point ``point`` (feet 0, 1; joints 2, 3; rotors 4, 5) touched last step."""
    return st[lay.S_CM + point] != 0.0


@njit(cache=True)
def normal_force(st, point):
    """Normal force on a contact point last step (N)."""
    return st[lay.S_NF + point]


@njit(cache=True)
def friction_force(st, point):
    """Force along the surface on a contact point last step (N, toward +x along the surface)."""
    return st[lay.S_FT + point]


@njit(cache=True)
def foot_normal_force(st, leg):
    return st[lay.S_NF + leg]


@njit(cache=True)
def peak_foot_load(st):
    """Largest normal force either foot has carried this landing (N): what the rigid gear's
    structural limit (``rigid_load_limit``) is checked against."""
    return st[lay.S_NPEAK]


@njit(cache=True)
def foot_slip_speed(st, leg):
    """Speed of the leg's foot along the surface last step (m/s, downhill-positive; toward +x
    on level ground)."""
    return st[lay.S_SLIP + leg]


@njit(cache=True)
def rotor_thrust(st, rotor):
    """Thrust of rotor 0 (-x) or 1 (+x) last step (N)."""
    return st[lay.S_THR + rotor]


@njit(cache=True)
def touchdown_time(st):
    """Time of first contact (s); negative before it."""
    return st[lay.S_TIMP]


@njit(cache=True)
def slope_sin(ctx):
    return ctx[lay.C_SIN]


@njit(cache=True)
def slope_cos(ctx):
    return ctx[lay.C_COS]


@njit(cache=True)
def downhill_leg(ctx):
    """Index of the downhill leg (0 = C, 1 = D)."""
    return int(ctx[lay.C_DOWN])


@njit(cache=True)
def torque_setting(ctx, leg):
    """The leg's set friction torque (planar: the per-joint torque x joints per planar leg)."""
    return ctx[lay.C_TAU + leg]


@njit(cache=True)
def initial_leg_angle(ctx, leg):
    """The leg angle the compression is measured from (rad)."""
    return ctx[lay.C_QINIT + leg]


@njit(cache=True)
def ground_stiffness(ctx):
    """The model's ground stiffness (N/m) at the point a normal-force law is called for: a
    law that scales or blends with the built-in spring-damper reads it here."""
    return ctx[lay.C_KG]


@njit(cache=True)
def ground_damping(ctx):
    """The model's ground damping (N*s/m) at the point a normal-force law is called for."""
    return ctx[lay.C_BG]


@njit(cache=True)
def memory(st, ctx, i):
    """The calling effect's ``i``-th state (its memory, in the order its ``states`` declare
    them): what its functions left there, or the initial value."""
    return st[lay.S_MEM + int(ctx[lay.C_MEM]) + i]


@njit(cache=True)
def set_memory(st, ctx, i, value):
    """Set the calling effect's ``i``-th state; the integrator carries it to the next step
    (write it from the effect's ``update``, which runs once per step after the step)."""
    st[lay.S_MEM + int(ctx[lay.C_MEM]) + i] = value


@njit(cache=True)
def joint_load(ctx):
    """In a joint-torque law: the torque the leg puts on the friction joint at the start of the
    step (planar N*m, positive pushing it toward extension, negative toward compression); its
    sign says which way the joint would slip. Set by the integrator just before it calls the law."""
    return ctx[lay.C_JLOAD]
