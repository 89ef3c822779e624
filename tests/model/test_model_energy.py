"""Energy: conserved with every dissipative effect off, and with them on, the energy lost
equals the work of the joints' friction, the dampers and the feet."""

from dataclasses import replace

import pytest

from slopelander.model.stepper import Stepper


def _drop(model, slope, dt, seconds=0.6, speed=2.0, tau=1.7):
    m = replace(model, dt=dt)
    s = Stepper(m, slope_deg=slope)
    s.set_friction(tau, tau)
    s.place(height=0.0, vz=-speed, pitch_rate_dps=30.0)
    e0 = sum(s.energy().values())
    for _ in range(int(seconds / 1e-3)):
        s.step(1e-3, 0.0, 0.0)
    return e0, sum(s.energy().values()), s.dissipated()


def test_conservative_model_keeps_its_energy(model):
    # legs bend on their flex springs, feet bounce on undamped ground springs and slide
    # without friction; joints never slip; springs explicit (symplectic)
    cons = replace(model, effects=("leg_flex",), implicit_springs=False).with_params(
        flex_damping=1e-6, ground_damping=0.0, eot_damping=0.0
    )
    e0, e1, diss = _drop(cons, slope=15.0, dt=2.5e-5, tau=9.0)
    assert e0 > 5.0
    assert diss["joint_friction"] == 0.0
    assert e1 == pytest.approx(e0, rel=5e-3)


def test_energy_lost_equals_dissipated_work(model):
    errors = []
    for dt in (2.5e-4, 2.5e-5):
        e0, e1, diss = _drop(model, slope=20.0, dt=dt)
        lost = e0 - e1
        assert diss["joint_friction"] > 0.05 and diss["foot_friction"] > 0.5
        assert diss["rotor_work"] == 0.0
        errors.append(abs(lost - sum(diss.values())) / lost)
    assert errors[0] < 0.05
    assert errors[1] < 0.02
    assert errors[1] < errors[0]  # the balance closes as the step shrinks


def test_rotor_work_is_counted(model):
    """Climbing from hover at full thrust: the energy gained is the rotors' work."""
    s = Stepper(model, slope_deg=0.0)
    u = s.hover_command()
    s.place(height=1.0, rotor_speed=u)
    e0 = sum(s.energy().values())
    for _ in range(600):
        s.step(1 / 1200, 1.0, 1.0)
    d = s.dissipated()
    gained = sum(s.energy().values()) - e0
    assert s.body().vz > 1.0
    assert d["rotor_work"] > 5.0
    assert gained == pytest.approx(d["rotor_work"], rel=0.01)


def test_rigid_skids_book_their_own_contact_energy(model):
    # the rigid gear's feet on their own (lightly damped) skid contact: the energy lost is the
    # skid dampers' and the feet's friction work, and the spring energy is the skid spring's
    rigid = model.rigid()
    errors = []
    for dt in (2.5e-4, 2.5e-5):
        e0, e1, diss = _drop(rigid, slope=10.0, dt=dt, speed=1.0)
        lost = e0 - e1
        assert diss["ground_damper"] > 0.1 and diss["joint_friction"] == 0.0
        errors.append(abs(lost - sum(diss.values())) / lost)
    assert errors[1] < 0.02
    assert errors[1] < errors[0]
