"""Helpers shared by the model tests (imported by name: this folder is on sys.path)."""

from dataclasses import replace

from slopelander.model import LandingConditions, Model
from slopelander.model.placement import settle_on_slope, slide_after  # noqa: F401 (re-exported)


def with_dt(model: Model, dt: float) -> Model:
    return replace(model, dt=dt)


#: landing 9 of the outdoor campaign: a 42 deg roof, 2.25 m/s, the table's preset and uphill angle,
#: full reverse thrust (the landing the thrust-end tests are built on)
ROOF = LandingConditions(
    slope_deg=42.0,
    speed=2.25,
    tau_up=1.1,
    tau_down=1.7,
    angle_up_deg=22.3125,
    angle_down_deg=37.5,
    reverse_percent=100.0,
)
