"""The ground the vehicle flies over: a level take-off pad and a sloped roof beside it.

The model's physics knows one plane surface through its origin. The world keeps the offset of
the model's frame, and while the vehicle is airborne it hands the physics the surface under it:
the pad (level, height 0) for x < roof_x, the roof (slope down toward +x from its top edge at
(roof_x, roof_z)) beyond. No walls: flying into the roof's edge from below is not modelled.

The rangefinder sees the whole world, not only the physics' plane (:func:`world_beam`): the pad,
the roof's top edge (a step up from the pad, or a ridge with a second face falling back to the
pad), the roof face down to its gutter, and nothing in range beyond the gutter. Its beam has a
width: a fan of rays whose mean (a lidar's centroid) or nearest (a sonar's first echo) range is
read; a fan straddling a jump in range (an edge, the gutter) returns nothing.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

from sitl.vehicle.scenario import Scenario
from slopelander.model.stepper import Stepper


@dataclass(frozen=True)
class Beam:
    """The rangefinder's beam: full width (deg), what it returns, and the jump between two
    neighbouring rays (m) above which the return is lost."""

    width_deg: float = 2.0
    mode: str = "mean"  # mean | nearest
    edge_dropout_m: float = 0.1
    rays: int = 7


#: the longest roof (m along x) when the scenario gives no gutter
NO_GUTTER_M = 1e4
_FAR_M = 1e6


@dataclass
class World:
    roof_slope_deg: float = 20.0
    roof_x: float = 3.0  # m, world x of the roof's top edge
    roof_z: float = 0.5  # m, height of that edge above the pad
    ox: float = 0.0  # world position of the model frame's origin
    oz: float = 0.0
    on_roof: bool = False
    #: "step": the pad meets the top edge in a vertical step; "gable": a second roof face falls
    #: from the ridge back toward -x at the same slope down to the pad
    ridge: str = "step"
    roof_length: float = NO_GUTTER_M  # m along x from the top edge to the gutter
    beam: Beam = Beam()
    _segs: tuple | None = field(default=None, repr=False, compare=False)

    def segments(self) -> list[tuple[float, float, float, float]]:
        """The surface the rangefinder sees as (x0, z0, x1, z1) segments, -x to +x."""
        key = (self.roof_slope_deg, self.roof_x, self.roof_z, self.ridge, self.roof_length)
        if self._segs is None or self._segs[0] != key:
            self._segs = (key, self._build_segments())
        return self._segs[1]

    def _build_segments(self) -> list[tuple[float, float, float, float]]:
        t = math.tan(math.radians(self.roof_slope_deg))
        x0, z0 = self.roof_x, self.roof_z
        foot = x0 - z0 / t if self.ridge == "gable" and z0 > 0 and t > 1e-6 else x0
        segs = [(-_FAR_M, 0.0, foot, 0.0), (foot, 0.0, x0, z0)]
        length = min(self.roof_length, NO_GUTTER_M)
        segs.append((x0, z0, x0 + length, z0 - length * t))
        return segs

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
        _t, x, z = stepper.motion()[:3]  # every physics step: no BodyState built
        xw, zw = x + self.ox, z + self.oz  # to_world
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


def ray_hit(
    segs: list[tuple[float, float, float, float]], x: float, z: float, dx: float, dz: float
) -> tuple[float, int]:
    """Distance from (x, z) along the unit direction (dx, dz) to the nearest segment and that
    segment's index; (inf, -1) when it meets none."""
    best, which = math.inf, -1
    for k, (x0, z0, x1, z1) in enumerate(segs):
        ex, ez = x1 - x0, z1 - z0
        den = dx * ez - dz * ex
        if abs(den) < 1e-12:
            continue
        wx, wz = x0 - x, z0 - z
        s = (wx * ez - wz * ex) / den
        u = (wx * dz - wz * dx) / den
        if s > 0.0 and -1e-9 <= u <= 1.0 + 1e-9 and s < best:
            best, which = s, k
    return best, which


def world_beam(stepper: Stepper, world: World) -> float:
    """What the rangefinder reads (m) over the world's surface (:meth:`World.segments`): the
    beam's rays from the body origin around the body's down axis; their mean or nearest range
    (``world.beam.mode``); NaN (no data) when neighbouring rays differ by more than
    ``edge_dropout_m`` or some miss (the footprint straddles an edge); inf when all miss. Below
    the physics' own surface it reads 0, as :func:`beam_range` does."""
    _t, bx, bz, pitch = stepper.motion()[:4]
    a = math.radians(stepper.slope_deg)
    if bx * math.sin(a) + bz * math.cos(a) <= 0.0:
        return 0.0
    x, z = world.to_world(bx, bz)
    return beam_at(world, x, z, pitch)


def beam_at(world: World, x: float, z: float, pitch: float) -> float:
    """:func:`world_beam` for a body origin at world (x, z up) pitched ``pitch`` (rad, nose up)."""
    bm = world.beam
    segs = world.segments()
    n = bm.rays if bm.width_deg > 0 else 1
    half = math.radians(bm.width_deg) / 2
    angles = [pitch + (-half + 2 * half * i / (n - 1) if n > 1 else 0.0) for i in range(n)]
    first = ray_hit(segs, x, z, math.sin(angles[0]), -math.cos(angles[0]))
    last = ray_hit(segs, x, z, math.sin(angles[-1]), -math.cos(angles[-1]))
    if first[1] >= 0 and first[1] == last[1]:
        # the whole footprint on one segment: each ray's range to its line in closed form
        x0, z0, x1, z1 = segs[first[1]]
        ex, ez = x1 - x0, z1 - z0
        wx, wz = x0 - x, z0 - z
        num = wx * ez - wz * ex
        ranges = [num / (math.sin(g) * ez + math.cos(g) * ex) for g in angles]
    else:
        ranges = [ray_hit(segs, x, z, math.sin(g), -math.cos(g))[0] for g in angles]
    hits = [r for r in ranges if math.isfinite(r)]
    if not hits:
        return math.inf
    if len(hits) < n:
        return math.nan
    if any(abs(p - q) > bm.edge_dropout_m for p, q in itertools.pairwise(ranges)):
        return math.nan
    return min(hits) if bm.mode == "nearest" else sum(hits) / n


def start_on_ground(scenario: Scenario) -> tuple[Stepper, World]:
    """The model and its world with the vehicle settled where the scenario starts it (pad or
    roof); shared by every simulator that runs the model so they start alike."""
    stepper = Stepper(scenario.model())
    world = World(
        scenario.slope_deg,
        scenario.roof_x,
        scenario.roof_z,
        ridge=scenario.ridge,
        roof_length=scenario.roof_length,
        beam=Beam(scenario.beam_width_deg, scenario.beam_return, scenario.edge_dropout_m),
    )
    if scenario.start_on == "roof":
        stepper.set_slope(scenario.slope_deg, scenario.roof_x, scenario.roof_z)
        world.ox, world.oz, world.on_roof = scenario.roof_x, scenario.roof_z, True
    stepper.place(height=0.0, x=scenario.start_x - world.ox)
    stepper.step(0.5, 0.0, 0.0)  # settle on the ground
    return stepper, world
