"""The ground the vehicle flies over: a level take-off pad and a sloped roof beside it.

The model's physics knows one plane surface through its origin. The world keeps the offset of
the model's frame, and while the vehicle is airborne it hands the physics the surface under it:
the pad (level, height 0) for x < roof_x, the roof (slope down toward +x from its top edge at
(roof_x, roof_z)) beyond. No walls: flying into the roof's edge from below is not modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sitl.vehicle.scenario import Scenario
from slopelander.model.stepper import Stepper


@dataclass
class World:
    roof_slope_deg: float = 20.0
    roof_x: float = 3.0  # m, world x of the roof's top edge
    roof_z: float = 0.5  # m, height of that edge above the pad
    ox: float = 0.0  # world position of the model frame's origin
    oz: float = 0.0
    on_roof: bool = False

    def surface_under(self, x_world: float) -> tuple[bool, float, float, float]:
        """(is roof, slope deg, origin x, origin z) of the surface below world x."""
        if x_world >= self.roof_x:
            return True, self.roof_slope_deg, self.roof_x, self.roof_z
        return False, 0.0, 0.0, 0.0

    def surface_z(self, x_world: float) -> float:
        _roof, slope, x0, z0 = self.surface_under(x_world)
        return z0 - (x_world - x0) * math.tan(math.radians(slope))

    def to_world(self, x: float, z: float) -> tuple[float, float]:
        return x + self.ox, z + self.oz

    def update(self, stepper: Stepper) -> bool:
        """Switch the physics to the surface under the vehicle if it is airborne and clear of
        that surface; True when it switched."""
        b = stepper.body()
        xw, zw = self.to_world(b.x, b.z)
        roof, slope, x0, z0 = self.surface_under(xw)
        if roof == self.on_roof or stepper.in_contact():
            return False
        # clearance of the body origin above the new surface (along its normal), with margin
        a = math.radians(slope)
        if (xw - x0) * math.sin(a) + (zw - z0) * math.cos(a) < 0.35:
            return False
        stepper.set_slope(slope, x0 - self.ox, z0 - self.oz)
        self.ox, self.oz, self.on_roof = x0, z0, roof
        return True


def beam_range(stepper: Stepper) -> float:
    """Distance (m) from the body origin along the body's down axis to the physics surface;
    inf when the beam points away from it."""
    b = stepper.body()
    a = math.radians(stepper.slope_deg)
    c = math.cos(a + b.pitch)
    if c < 0.05:
        return math.inf
    h = b.x * math.sin(a) + b.z * math.cos(a)
    return h / c if h > 0 else 0.0


def start_on_ground(scenario: Scenario) -> tuple[Stepper, World]:
    """The model and its world with the vehicle settled where the scenario starts it (pad or
    roof); shared by every simulator that runs the model so they start alike."""
    stepper = Stepper(scenario.model())
    world = World(scenario.slope_deg, scenario.roof_x, scenario.roof_z)
    if scenario.start_on == "roof":
        stepper.set_slope(scenario.slope_deg, scenario.roof_x, scenario.roof_z)
        world.ox, world.oz, world.on_roof = scenario.roof_x, scenario.roof_z, True
    stepper.place(height=0.0, x=scenario.start_x - world.ox)
    stepper.step(0.5, 0.0, 0.0)  # settle on the ground
    return stepper, world
