"""Reference landings that pin the integrator's arithmetic across refactorings.

``python3 tests/model/kernel_reference.py`` records them (into
``tests/model/data/kernel_reference.npz``) from the integrator as it is; the test
``test_kernel_reference.py`` runs the same cases and compares. Record again only for a change
meant to move the trajectories, and say so in the commit.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from slopelander.model import LandingConditions, Model, load_effects, simulate, simulate_batch
from slopelander.model.stepper import Stepper

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data" / "kernel_reference.npz"
EXAMPLES = ROOT / "docs" / "examples"


def _user(*names: str) -> tuple:
    return tuple(e for n in names for e in load_effects(EXAMPLES / f"effect_{n}.py"))


def landing_cases() -> dict[str, tuple[LandingConditions, Model]]:
    """Several slopes, speeds and presets, built-in variants, and the docs' user effects."""
    m = Model.default()
    L = LandingConditions
    return {
        "level_2ms": (L(), m),
        "slope20_presets": (
            L(20.0, 3.0, horizontal_speed=0.5, pitch_deg=5.0, tau_up=1.0, tau_down=2.5, angle_up_deg=30.0),
            m,
        ),
        "slope35_reverse": (
            L(35.0, 4.0, reverse_percent=60.0, reverse_delay=0.02, reverse_duration=0.3, reverse_ramp=0.1),
            m,
        ),
        "slope_minus25_rate": (L(-25.0, 1.5, pitch_rate_dps=30.0, tau_up=2.3, tau_down=1.2), m),
        "slope42_slides": (L(42.0, 1.0, tau_up=2.3, tau_down=2.3, angle_up_deg=24.0), m),
        "rigid_slope15": (L(15.0, 2.0), m.rigid()),
        "regularised_slope10": (
            L(10.0, 2.5),
            m.without("foot_stiction", "velocity_weakening_friction").with_effects("regularised_friction"),
        ),
        "explicit_springs": (L(0.0, 1.5), replace(m, implicit_springs=False)),
        "no_flex_slope20": (L(20.0, 2.5, tau_up=0.8, tau_down=0.8), m.without("leg_flex")),
        "user_foot_friction": (
            L(42.0, 1.0, tau_up=2.3, tau_down=2.3, angle_up_deg=24.0),
            replace(m, user_effects=_user("foot_friction")),
        ),
        "user_all_seams": (
            L(20.0, 2.5, tau_up=0.56, tau_down=0.9, horizontal_speed=0.3),
            replace(
                m,
                user_effects=_user(
                    "joint_torque", "torque_growth", "foot_friction", "point_force", "normal_force"
                ),
            ).with_params(joint_viscous_gain=0.1, drag_coefficient=0.5),
        ),
    }


BATCH = [
    LandingConditions(s, v, tau_up=t, tau_down=t)
    for s in (0.0, 15.0, 30.0)
    for v in (1.5, 3.0)
    for t in (0.8, 2.0)
]


def stepper_run(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """The simulated vehicle's path: hover, a gust, a touchdown, reverse thrust; the state
    every 10 ticks of 1200 Hz and the final energy terms."""
    s = Stepper(model, slope_deg=12.0)
    s.set_friction(1.2, 1.9)
    s.place(height=0.15, vz=-1.0, rotor_speed=0.5)
    hover = s.hover_command()
    out = []
    for i in range(720):
        if i == 100:
            s.set_external_force(fx=3.0, torque=0.2)
        u = hover * 0.9 if i < 300 else -0.6
        s.step(1.0 / 1200.0, u, u * 0.95)
        if i % 10 == 9:
            out.append(s.st.copy())
    return np.array(out), np.array(list(s.energy().values()))


def run_all() -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for name, (c, model) in landing_cases().items():
        tr = simulate(c, model)
        out[f"landing/{name}"] = tr.raw
    for name, model in (
        ("default", Model.default()),
        ("user", replace(Model.default(), user_effects=_user("point_force"))),
    ):
        st, en = stepper_run(model)
        out[f"stepper/{name}"] = st
        out[f"energy/{name}"] = en
    res = simulate_batch(BATCH, Model.default())
    out["batch/default"] = np.column_stack([res[n].astype(np.float64) for n in res.dtype.names])
    return out


if __name__ == "__main__":
    data = run_all()
    DATA.parent.mkdir(exist_ok=True)
    np.savez_compressed(DATA, **data)
    print(f"wrote {len(data)} arrays to {DATA}", file=sys.stderr)
