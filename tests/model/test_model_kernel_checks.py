"""The kernel's mass matrix, generalised forces and Jacobians against finite differences of
positions and energy, and its hand-numbered index layouts against the field orders they mirror.

``kinematics`` is shared by the compiled integrator and the scipy reference, so an error in it
would pass every comparison between the two: this checks it against nothing but point positions.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from slopelander.model import kernel as k
from slopelander.model import layout
from slopelander.model.conditions import CONDITION_FIELDS, LandingConditions, conditions_array
from slopelander.model.effects import BUILTIN_EFFECTS
from slopelander.model.landing import Model
from slopelander.model.outcome import RESULT_FIELDS, OutcomeCriteria
from slopelander.model.parameters import PARAMETER_NAMES

P = Model.default().params.as_array().copy()
EPS = 1e-6

# generalised coordinates: x, z, pitch, q_C, q_D (legs a little compressed, body pitched)
CONFIGS = [
    np.array([0.01, 0.2, 0.3, math.radians(30.0), math.radians(20.0)]),
    np.array([-0.3, 0.1, -0.8, math.radians(5.0), math.radians(37.0)]),
    np.array([0.0, 0.0, 1.2, math.radians(12.0), math.radians(12.0)]),
]


def _kin(Q: np.ndarray, V: np.ndarray | None = None):
    st = np.zeros(k.N_STATE)
    st[k.S_Q : k.S_Q + 5] = Q
    st[k.S_V : k.S_V + 5] = np.zeros(5) if V is None else V
    ws = k.make_workspace()
    M, f, pts, vel, J = k.kinematics_views(ws)
    k.kinematics(P, st, M, f, pts, vel, J)
    return M.copy(), f.copy(), pts.copy(), vel.copy(), J.copy()


def _points(Q: np.ndarray) -> np.ndarray:
    return _kin(Q)[2]


def _legs(Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each leg's centre of mass (mid-point of joint and foot: a uniform rod) and world angle."""
    pts = _points(Q)
    feet, joints = pts[0:2], pts[2:4]
    d = feet - joints
    return (feet + joints) / 2, np.arctan2(d[:, 1], d[:, 0])


def _rate(fn, Q: np.ndarray, V: np.ndarray) -> np.ndarray:
    """d/dt of fn(Q) moving with velocity V, by a central difference."""
    h = 1e-6
    return (fn(Q + h * V) - fn(Q - h * V)) / (2 * h)


def _kinetic_energy(Q: np.ndarray, V: np.ndarray) -> float:
    """From positions alone: body translation and rotation, each leg's centre and rotation."""
    mb, ib, ml, il = (P[k.P_MB], P[k.P_IB], P[k.P_ML], P[k.P_IL])
    com_rate = _rate(lambda q: _legs(q)[0], Q, V)
    angle_rate = _rate(lambda q: np.unwrap(_legs(q)[1]), Q, V)
    return float(
        0.5 * mb * (V[0] ** 2 + V[1] ** 2)
        + 0.5 * ib * V[2] ** 2
        + 0.5 * ml * (com_rate**2).sum()
        + 0.5 * il * (angle_rate**2).sum()
    )


def _potential(Q: np.ndarray) -> float:
    g = P[k.P_G]
    return float(g * (P[k.P_MB] * Q[1] + P[k.P_ML] * _legs(Q)[0][:, 1].sum()))


@pytest.mark.parametrize("Q", CONFIGS)
def test_jacobians_are_the_derivatives_of_the_point_positions(Q: np.ndarray) -> None:
    J = _kin(Q)[4]
    fd = np.zeros_like(J)
    for b in range(5):
        e = np.zeros(5)
        e[b] = EPS
        fd[:, :, b] = (_points(Q + e) - _points(Q - e)) / (2 * EPS)
    np.testing.assert_allclose(J, fd, atol=1e-8)
    V = np.array([0.3, -2.0, 1.5, -4.0, 2.5])
    np.testing.assert_allclose(_kin(Q, V)[3], _rate(_points, Q, V), atol=1e-7)


@pytest.mark.parametrize("Q", CONFIGS)
def test_the_mass_matrix_gives_the_kinetic_energy_of_the_moving_bodies(Q: np.ndarray) -> None:
    M = _kin(Q)[0]
    np.testing.assert_allclose(M, M.T, atol=1e-15)
    # every entry, by polarisation: T(e_a + e_b) - T(e_a) - T(e_b) = M_ab
    I = np.eye(5)
    T = np.array([_kinetic_energy(Q, I[a]) for a in range(5)])
    fd = np.diag(2 * T)
    for a in range(5):
        for b in range(a + 1, 5):
            fd[a, b] = fd[b, a] = _kinetic_energy(Q, I[a] + I[b]) - T[a] - T[b]
    np.testing.assert_allclose(M, fd, rtol=1e-6, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(M) > 0)


@pytest.mark.parametrize("Q", CONFIGS)
def test_gravity_forces_are_minus_the_gradient_of_the_potential(Q: np.ndarray) -> None:
    f = _kin(Q)[1]  # at rest: gravity only
    grad = np.array([(_potential(Q + EPS * e) - _potential(Q - EPS * e)) / (2 * EPS) for e in np.eye(5)])
    np.testing.assert_allclose(f, -grad, rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("Q", CONFIGS)
def test_velocity_product_forces_follow_from_the_mass_matrix(Q: np.ndarray) -> None:
    """Lagrange: M a = f, with f = gravity - (dM/dt v - 1/2 d(v' M v)/dQ)."""
    V = np.array([0.4, -1.5, 3.0, -6.0, 4.0])
    M = lambda q: _kin(q)[0]  # noqa: E731
    dM_dt = _rate(M, Q, V)
    grad = np.array([(V @ M(Q + EPS * e) @ V - V @ M(Q - EPS * e) @ V) / (2 * EPS) for e in np.eye(5)])
    expected = _kin(Q)[1] - (dM_dt @ V - 0.5 * grad)
    np.testing.assert_allclose(_kin(Q, V)[1], expected, rtol=1e-6, atol=1e-6)


# -- index layouts ---------------------------------------------------------------------------
def _constants(prefix: str) -> dict[str, int]:
    """Integer constants named ``prefix...`` where the layout is defined (layout.py), else the kernel."""
    src = layout if any(n.startswith(prefix) for n in dir(layout)) else k
    return {n: getattr(src, n) for n in dir(src) if n.startswith(prefix) and isinstance(getattr(src, n), int)}


def _coverage(starts: dict[str, int], widths: dict[str, int], total: int) -> list[int]:
    """How many of the blocks [start, start + width) cover each slot 0..total-1 (tiling: all 1)."""
    cover = np.zeros(total, int)
    for name, start in starts.items():
        cover[start : start + widths[name]] += 1
    return cover.tolist()


def test_parameter_indices_cover_every_parameter_once() -> None:
    p = _constants("P_")
    assert sorted(p.values()) == list(range(len(PARAMETER_NAMES)))
    # spot checks of names against the parameter they index
    assert PARAMETER_NAMES[k.P_MB] == "body_mass" and PARAMETER_NAMES[k.P_DELAY] == "rotor_reversal_delay"


def test_state_layout_tiles_the_state_vector() -> None:
    widths = {
        "S_Q": 5,
        "S_V": 5,
        "S_QE": 2,
        "S_JM": 2,
        "S_CM": k.N_POINTS,
        "S_ANC": k.N_POINTS,
        "S_W": 2,
        "S_DIR": 2,
        "S_WAIT": 2,
        "S_T": 1,
        "S_FF": 2,
        "S_TIMP": 1,
        "S_QEMIN": 2,
        "S_TOUCH": 1,
        "S_PMIN": 1,
        "S_PMAX": 1,
        "S_X0": 2,
        "S_REST": 1,
        "S_DISS": 6,
        "S_NF": k.N_POINTS,
        "S_FT": k.N_POINTS,
        "S_THR": 2,
        "S_REFINE": 1,
        "S_DUSER": 1,
        "S_SLIP": k.N_POINTS,
        "S_QED": 2,
        "S_NPEAK": 1,
        "S_MEM": layout.N_MEMORY,
    }
    starts = _constants("S_")
    assert set(starts) == set(widths), set(starts) ^ set(widths)
    assert _coverage(starts, widths, k.N_STATE) == [1] * k.N_STATE, sorted(
        starts.items(), key=lambda kv: kv[1]
    )


def test_context_layout_tiles_the_context_vector() -> None:
    widths = {
        "C_SIN": 1,
        "C_COS": 1,
        "C_DOWN": 1,
        "C_TAU": 2,
        "C_QINIT": 2,
        "C_FEXT": 3,
        "C_KG": 1,
        "C_BG": 1,
        "C_MEM": 1,
        "C_JLOAD": 1,
    }
    starts = _constants("C_")
    assert set(starts) == set(widths), set(starts) ^ set(widths)
    assert _coverage(starts, widths, k.N_CTX) == [1] * k.N_CTX, sorted(starts.items(), key=lambda kv: kv[1])


def test_effect_flags_are_distinct_and_fit_the_flag_array() -> None:
    flags = [e.flag for e in BUILTIN_EFFECTS.values()]
    assert len(set(flags)) == len(flags)
    assert set(flags) | {k.F_IMPLICIT_K} == set(range(k.N_FLAGS))
    assert k.F_IMPLICIT_K not in flags
    assert sorted(_constants("F_").values()) == list(range(k.N_FLAGS))


def test_condition_indices_follow_the_landing_conditions_fields() -> None:
    expected = {
        "K_SLOPE": "slope_deg",
        "K_SPEED": "speed",
        "K_VX": "horizontal_speed",
        "K_PITCH": "pitch_deg",
        "K_RATE": "pitch_rate_dps",
        "K_TAU_UP": "tau_up",
        "K_TAU_DOWN": "tau_down",
        "K_Q_UP": "angle_up_deg",
        "K_Q_DOWN": "angle_down_deg",
        "K_REV": "reverse_percent",
        "K_REVDLY": "reverse_delay",
        "K_REVDUR": "reverse_duration",
        "K_REVRAMP": "reverse_ramp",
    }
    assert set(_constants("K_")) == set(expected)
    assert {n: CONDITION_FIELDS[getattr(k, n)] for n in expected} == expected
    assert len(CONDITION_FIELDS) == k.N_COND


def test_criteria_indices_follow_the_outcome_criteria_fields() -> None:
    expected = {
        "R_HORIZON": "horizon",
        "R_SLIDE": "slide_limit",
        "R_UNDER": "underused_fraction",
        "R_FLIP": "flip_pitch_deg",
        "R_SPEED": "settle_speed",
        "R_RATE": "settle_rate_dps",
        "R_SETTLE": "settle_time",
    }
    names = [f.name for f in dataclasses.fields(OutcomeCriteria)]
    assert {n: names[getattr(k, n)] for n in expected} == expected
    crit = OutcomeCriteria(
        horizon=1.5,
        slide_limit=0.7,
        underused_fraction=0.3,
        flip_pitch_deg=70.0,
        settle_speed=0.03,
        settle_rate_dps=3.0,
        settle_time=0.2,
    )
    arr = dataclasses.replace(Model.default(), criteria=crit).criteria_array()
    assert {n: arr[getattr(k, n)] for n in expected} == {n: getattr(crit, f) for n, f in expected.items()}


def test_result_indices_follow_the_result_fields() -> None:
    expected = {
        "O_CODE": "outcome",
        "O_CUP": "compression_up",
        "O_CDOWN": "compression_down",
        "O_SLIDE": "slide",
        "O_PFINAL": "final_pitch_deg",
        "O_PMIN": "min_pitch_deg",
        "O_TSETTLE": "settle_time",
        "O_TEND": "t_end",
    }
    assert set(_constants("O_")) == set(expected)
    assert {n: RESULT_FIELDS[getattr(k, n)] for n in expected} == expected
    assert len(RESULT_FIELDS) == k.N_RESULT


def test_a_landing_leaves_the_jacobians_zero_columns_zero() -> None:
    """The kinematics writes only the Jacobian columns that move each point (x, z, pitch, a foot's
    own leg) and leaves the rest at the workspace's zeros: after half a second of a landing
    (touchdown, sliding, both feet on the ground) those entries, and the contact rows made from
    them, are still zero, and the workspace's kinematics of the last state equals a fresh one's."""
    model = Model.default()
    p, fl = model.params.as_array(), model.flags()
    c = LandingConditions(slope_deg=40.0, speed=3.0, horizontal_speed=0.5, pitch_deg=-10.0, tau_up=0.56)
    row = conditions_array([c]).view(np.float64).copy()
    st, ctx, ws = np.zeros(k.N_STATE), np.zeros(k.N_CTX), k.make_workspace()
    k.init_landing(p, fl, row, st, ctx, ws)
    touched = set()
    for _ in range(1200):
        k.step(p, fl, ctx, st, model.dt, 0.0, 0.0, ws, None)
        touched |= {i for i in range(k.N_POINTS) if st[k.S_NF + i] > 0.0}
    assert {0, 1} <= touched  # both feet bore load
    J, JNT = ws["J"][0], ws["JNT"][0]
    for i in range(k.N_POINTS):
        moving = {0, 1, 2} | ({3 + i} if i < 2 else set())
        for b in sorted(set(range(5)) - moving):
            assert not J[i, :, b].any() and not JNT[i, :, b].any(), (i, b)
    again, fresh = k.kinematics_views(ws), k.kinematics_views(k.make_workspace())
    assert k.kinematics(p, st, *again) == k.kinematics(p, st, *fresh)  # the pitch's cosine and sine
    for a, b in zip(again, fresh, strict=True):
        np.testing.assert_array_equal(a, b)


def test_no_compiled_function_steps_on_the_record_of_a_workspace_it_allocated():
    """numba frees an array after its last use in a function, and a record (``ws[0]``) does
    not keep its array alive: a function that allocates a workspace and then works through its
    record works on freed memory (landings with garbage results on Dask workers). The
    workspace must come in as an argument, which lives as long as the caller's reference."""
    import ast
    import inspect

    tree = ast.parse(inspect.getsource(k))
    offenders = []
    for fn in (n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)):
        allocated = {
            t.id
            for node in ast.walk(fn)
            if isinstance(node, ast.Assign)
            and isinstance(node.value, ast.Call)
            and getattr(node.value.func, "id", "") in ("_make_workspace_jit", "make_workspace")
            for t in node.targets
            if isinstance(t, ast.Name)
        }
        for node in ast.walk(fn):
            if isinstance(node, ast.Subscript) and getattr(node.value, "id", None) in allocated:
                offenders.append(f"{fn.name}: {ast.unparse(node)}")
    assert not offenders, offenders
