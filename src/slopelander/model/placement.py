"""A vehicle standing on a slope, for hold-angle and creep measurements (tests and benchmarks).

Set down with the real friction, the unloaded legs splay on touchdown and the feet start sliding,
which is a landing, not a placement; so the vehicle is set down with sticky feet first and then
given the model's own friction."""

from __future__ import annotations

import math

from slopelander.model.landing import Model
from slopelander.model.stepper import Stepper

PLACE_DT = 1e-3  # s, the fixed step these measurements use


def settle_on_slope(model: Model, slope_deg: float, tau: float = 5.0, seconds: float = 0.8) -> Stepper:
    """A vehicle at rest on the slope with joint torques ``tau`` (N·m), carrying ``model``'s friction."""
    sticky = model.with_params(friction_static=3.0, friction_kinetic=3.0)
    s = Stepper(sticky, slope_deg=slope_deg)
    s.set_friction(tau, tau)
    s.place(height=0.0, pitch_deg=-slope_deg)
    for _ in range(round(seconds / PLACE_DT)):
        s.step(PLACE_DT, 0.0, 0.0)
    real = Stepper(model, slope_deg=slope_deg)
    real.st[:] = s.st
    real.ctx[:] = s.ctx
    return real


def slide_after(s: Stepper, seconds: float) -> float:
    """Distance (m) the body moves down the slope over ``seconds``, rotors off."""
    b0 = s.body()
    for _ in range(round(seconds / PLACE_DT)):
        s.step(PLACE_DT, 0.0, 0.0)
    b = s.body()
    a = math.radians(s.slope_deg)
    return math.cos(a) * (b.x - b0.x) - math.sin(a) * (b.z - b0.z)
