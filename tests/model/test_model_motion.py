"""Flight physics: gravity, thrust and its lever arms, before anything touches the ground."""

import math

import pytest

from slopelander.model.stepper import Stepper


def test_free_fall_follows_half_g_t_squared(model):
    s = Stepper(model, slope_deg=10.0)
    s.place(height=5.0, vx=0.7, pitch_deg=5.0)
    b0 = s.body()
    for _ in range(600):
        s.step(1 / 1200, 0.0, 0.0)
    b = s.body()
    t = b.t - b0.t
    g = model.params["gravity"]
    assert t == pytest.approx(0.5)
    # semi-implicit Euler falls g*h*t/2 further than the exact parabola: allow twice that
    assert b.z - b0.z == pytest.approx(-0.5 * g * t * t, abs=g * model.dt * t)
    assert b.z - b0.z < -0.5 * g * t * t  # and the error has that sign
    assert b.x - b0.x == pytest.approx(0.7 * t, abs=1e-9)
    # no torque in free fall: attitude unchanged, legs unloaded
    assert b.pitch == pytest.approx(math.radians(5.0), abs=1e-12)
    assert b.pitch_rate == pytest.approx(0.0, abs=1e-12)
    # an accelerometer in free fall reads nothing
    fx, fz = s.specific_force_body()
    assert abs(fx) < 1e-6 and abs(fz) < 1e-6
    assert not s.in_contact()


def test_hover_command_holds_altitude_and_level(model):
    s = Stepper(model)
    u = s.hover_command()
    s.place(height=2.0, rotor_speed=u)
    z0 = s.body().z
    for _ in range(1200):
        s.step(1 / 1200, u, u)
    b = s.body()
    assert b.z - z0 == pytest.approx(0.0, abs=1e-4)
    assert b.pitch == pytest.approx(0.0, abs=1e-12)
    # hovering, the accelerometer reads +g along body z
    assert s.specific_force_body()[1] == pytest.approx(model.params["gravity"], rel=1e-6)


def test_more_thrust_on_the_left_pitches_nose_right_down(model):
    """Left (uphill, -x) rotor pushing harder tips the body toward +x: negative pitch,
    at the rate the lever arm and inertia predict."""
    s = Stepper(model)
    u = s.hover_command()
    s.place(height=2.0, rotor_speed=u)
    s.step(1 / 1200, u, u)  # thrust settles on the hover speed
    dt = 0.02
    hi, lo = 0.8, 0.6
    p = model.params
    # rotor speed responds first order; integrate the torque over the step's response
    s.step(dt, hi, lo)
    b = s.body()
    assert b.pitch_rate < 0.0
    tl, tr = s.thrust()
    assert tl > tr
    inertia = p["body_inertia"] + 2 * (p["leg_inertia"] + p["leg_mass"] * 0.1)  # legs ride along
    # upper bound: the final torque applied for the whole interval
    bound = (tl - tr) * p["rotor_arm"] / p["body_inertia"] * dt
    assert abs(b.pitch_rate) < bound
    assert abs(b.pitch_rate) > 0.3 * (tl - tr) * p["rotor_arm"] / inertia * dt


def test_reverse_thrust_waits_out_the_reversal_delay(model):
    s = Stepper(model)
    s.place(height=3.0)
    delay = model.params["rotor_reversal_delay"]
    t = 0.0
    while t < delay - 0.01:
        s.step(1 / 1200, -1.0, -1.0)
        t += 1 / 1200
        assert s.thrust() == (0.0, 0.0)
    for _ in range(240):
        s.step(1 / 1200, -1.0, -1.0)
    tl, tr = s.thrust()
    full_reverse = -model.params["rotor_thrust_max"] * model.params["rotor_reverse_ratio"]
    assert full_reverse < tl < 0.5 * full_reverse and tl == tr


def test_rotors_off_effect_gives_no_thrust(model):
    s = Stepper(model.without("rotors"))
    s.place(height=3.0)
    for _ in range(100):
        s.step(1 / 1200, 1.0, 1.0)
    assert s.thrust() == (0.0, 0.0)
