"""Helpers shared by the model tests (imported by name: this folder is on sys.path)."""

import math
from dataclasses import replace

from slopelander.model import Model
from slopelander.model.stepper import Stepper


def settle_on_slope(model: Model, slope_deg: float, tau: float = 5.0, seconds: float = 0.8) -> Stepper:
    """A vehicle standing at rest on the slope: set down with sticky feet, then given the
    model's own friction. (Set down with the real friction, the unloaded legs splay on
    touchdown and the feet start sliding, which is a landing, not a placement.)"""
    sticky = model.with_params(friction_static=3.0, friction_kinetic=3.0)
    s = Stepper(sticky, slope_deg=slope_deg)
    s.set_friction(tau, tau)
    s.place(height=0.0, pitch_deg=-slope_deg)
    for _ in range(int(seconds / 1e-3)):
        s.step(1e-3, 0.0, 0.0)
    real = Stepper(model, slope_deg=slope_deg)
    real.st[:] = s.st
    real.ctx[:] = s.ctx
    return real


def slide_after(s: Stepper, seconds: float) -> float:
    """Distance the body moves down the slope over ``seconds``."""
    b0 = s.body()
    for _ in range(int(seconds / 1e-3)):
        s.step(1e-3, 0.0, 0.0)
    b = s.body()
    a = math.radians(s.slope_deg)
    return math.cos(a) * (b.x - b0.x) - math.sin(a) * (b.z - b0.z)


def with_dt(model: Model, dt: float) -> Model:
    return replace(model, dt=dt)
