"""The ground the vehicle flies over: a level take-off pad and a sloped roof beside it.

The world is three-dimensional: the pad (level, height 0) south of ``roof_x`` (north, m), the roof
north of it, a plane through its top edge's point on the north axis, (roof_x, 0, roof_z), that
falls at ``roof_slope_deg`` toward ``fall_azimuth_deg`` (deg from north, clockwise: 0 falls north,
away from the pad, as every roof did before the azimuth existed; 90 falls east, across the way
the vehicle comes from the pad). The roof's outline stays where it is (north of ``roof_x``, to
its gutter ``roof_length`` further north); only its plane turns.

The model's physics is planar: it flies in the vertical plane along the vehicle's heading, its x
the heading. The world keeps that plane, a *slice* (its horizontal origin ``n0``, ``e0`` and
direction ``heading_deg``), and the offset of the model's frame along it (``ox``, ``oz``); world x
below means the distance along the slice. While the vehicle is airborne it hands the physics the
surface under it: the pad (level, height 0), or the roof's section along the heading (its slope
``atan(tan(slope) cos(heading - fall azimuth))``; a section falling toward the vehicle's back is
handed over level: the model's downhill is its +x, and the companion never lands facing uphill).
A turn of the heading (:meth:`World.turn`) starts a new slice through the vehicle, once it is
airborne and clear of the surface. No walls: flying into the roof's edge from below is not
modelled.

The rangefinder sees the whole world along the slice, not only the physics' plane
(:func:`world_beam`): the pad, the roof's top edge (a step up from the pad, or a ridge with a
second face falling back to the pad), the roof face down to its gutter, and nothing in range
beyond the gutter. Its beam has a width: a fan of rays in the pitch plane whose mean (a lidar's
centroid) or nearest (a sonar's first echo) range is read; a fan straddling a jump in range (an
edge, the gutter) returns nothing. With the body level across (the model has no roll) the beam
lies in the slice, so the slice's section is what it sees.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

from slopelander.model.stepper import Stepper
from slopelander_sitl.vehicle.scenario import Scenario


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
#: the body's origin must be this far (m, along the normal) over a surface the physics switches to
CLEAR_M = 0.35


@dataclass
class World:
    roof_slope_deg: float = 20.0
    roof_x: float = 3.0  # m, north of the roof's top edge
    roof_z: float = 0.5  # m, height of that edge above the pad (on the north axis)
    ox: float = 0.0  # position of the model frame's origin along the slice
    oz: float = 0.0
    on_roof: bool = False
    #: "step": the pad meets the top edge in a vertical step; "gable": a second roof face falls
    #: from the ridge back toward -x at the same slope down to the pad (a roof falling north only)
    ridge: str = "step"
    roof_length: float = NO_GUTTER_M  # m north from the top edge to the gutter
    beam: Beam = Beam()
    fall_azimuth_deg: float = 0.0  # where the roof falls, deg from north, clockwise
    heading_deg: float = 0.0  # the slice's direction: the vehicle's heading
    n0: float = 0.0  # the slice's horizontal origin (north, east), m
    e0: float = 0.0
    _segs: tuple | None = field(default=None, repr=False, compare=False)

    # -- the slice ---------------------------------------------------------------------------
    def _dir(self) -> tuple[float, float]:
        a = math.radians(self.heading_deg)
        return math.cos(a), math.sin(a)

    def ne(self, x_world: float) -> tuple[float, float]:
        """(north, east) of the point ``x_world`` along the slice."""
        c, s = self._dir()
        return self.n0 + x_world * c, self.e0 + x_world * s

    def slice_x(self, north: float, east: float) -> float:
        """The distance along the slice of the point nearest (north, east) on it."""
        c, s = self._dir()
        return (north - self.n0) * c + (east - self.e0) * s

    def roof_height(self, north: float, east: float) -> float:
        """The roof's plane (extended) at (north, east)."""
        t = math.tan(math.radians(self.roof_slope_deg))
        f = math.radians(self.fall_azimuth_deg)
        return self.roof_z - t * ((north - self.roof_x) * math.cos(f) + east * math.sin(f))

    def section_slope_deg(self, turn_deg: float = 0.0) -> float:
        """The roof's slope along the slice (deg, positive falling toward +x), or along the slice
        turned by ``turn_deg`` clockwise (90: falling to the vehicle's right)."""
        if turn_deg:
            a = math.radians(self.heading_deg + turn_deg)
            f = math.radians(self.fall_azimuth_deg)
            k = math.cos(a) * math.cos(f) + math.sin(a) * math.sin(f)
            return math.degrees(math.atan(math.tan(math.radians(self.roof_slope_deg)) * k))
        c, s = self._dir()
        f = math.radians(self.fall_azimuth_deg)
        k = c * math.cos(f) + s * math.sin(f)
        if k == 1.0:  # along the fall line: the roof's own slope, to the bit
            return self.roof_slope_deg
        return math.degrees(math.atan(math.tan(math.radians(self.roof_slope_deg)) * k))

    # -- the surface -------------------------------------------------------------------------
    def segments(self) -> list[tuple[float, float, float, float]]:
        """The surface the rangefinder sees as (x0, z0, x1, z1) segments along the slice."""
        key = (
            self.roof_slope_deg,
            self.roof_x,
            self.roof_z,
            self.ridge,
            self.roof_length,
            self.fall_azimuth_deg,
            self.heading_deg,
            self.n0,
            self.e0,
        )
        if self._segs is None or self._segs[0] != key:
            self._segs = (key, self._build_segments())
        return self._segs[1]

    def _build_segments(self) -> list[tuple[float, float, float, float]]:
        t = math.tan(math.radians(self.roof_slope_deg))
        x0, z0 = self.roof_x, self.roof_z
        foot = x0 - z0 / t if self.ridge == "gable" and z0 > 0 and t > 1e-6 else x0
        gutter = x0 + min(self.roof_length, NO_GUTTER_M)
        c, _s = self._dir()
        if abs(c) < 1e-9:  # along the top edge: one surface, or none beyond the gutter
            n = self.n0
            if n < foot:
                return [(-_FAR_M, 0.0, _FAR_M, 0.0)]
            if n > gutter:
                return []
            if n < x0:  # on the gable face, level along the edge
                z = z0 - (x0 - n) * t
                return [(-_FAR_M, z, _FAR_M, z)]
            za, zb = (self.roof_height(*self.ne(x)) for x in (-_FAR_M, _FAR_M))
            return [(-_FAR_M, za, _FAR_M, zb)]

        def along(n: float) -> float:
            return (n - self.n0) / c

        def roof_at(n: float) -> float:
            return self.roof_height(n, self.ne(along(n))[1])

        far_n = self.n0 - _FAR_M * abs(c)  # far south on the slice
        # north-ordered pieces: the pad, the gable face (or the step), the roof to its gutter
        segs = [
            (along(far_n), 0.0, along(foot), 0.0),
            (along(foot), 0.0, along(x0), z0 if self.fall_azimuth_deg == 0.0 else roof_at(x0)),
            (along(x0), roof_at(x0), along(gutter), roof_at(gutter)),
        ]
        if self.fall_azimuth_deg == 0.0 and c == 1.0 and self.n0 == 0.0:
            # the roof falling north along the north axis: the segments as they always were
            segs[2] = (x0, z0, gutter, z0 - min(self.roof_length, NO_GUTTER_M) * t)
        return segs

    def surface_under(self, x_world: float) -> tuple[bool, float, float, float]:
        """(is roof, slope deg, origin x, origin z) of the physics' surface below world x: the
        pad, or the roof's section along the slice through the point where the slice meets the
        roof's top edge (on a slice nearly along that edge, the point below x); a section falling
        toward -x level, through the roof's point below x."""
        n, _e = self.ne(x_world)
        if n < self.roof_x:
            return False, 0.0, 0.0, 0.0
        if self.heading_deg == 0.0 and self.n0 == 0.0 and self.fall_azimuth_deg == 0.0:
            return True, self.roof_slope_deg, self.roof_x, self.roof_z  # as it always was
        c, _s = self._dir()
        section = self.section_slope_deg()
        # a section falling toward -x is handed over level, at the roof's height below x
        x0 = (self.roof_x - self.n0) / c if abs(c) >= 0.1 and section >= 0.0 else x_world
        z0 = self.roof_height(*self.ne(x0))
        return True, max(0.0, section), x0, z0

    def surface_z(self, x_world: float) -> float:
        """The height of the surface below world x (the roof's true section, not the physics')."""
        n, e = self.ne(x_world)
        if n < self.roof_x:
            return 0.0
        if self.heading_deg == 0.0 and self.n0 == 0.0 and self.fall_azimuth_deg == 0.0:
            return self.roof_z - (x_world - self.roof_x) * math.tan(math.radians(self.roof_slope_deg))
        return self.roof_height(n, e)

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
        if (xw - x0) * math.sin(a) + (zw - z0) * math.cos(a) < CLEAR_M:
            return False
        stepper.set_slope(slope, x0 - self.ox, z0 - self.oz)
        self.ox, self.oz, self.on_roof = x0, z0, roof
        return True

    def turn(self, stepper: Stepper, heading_deg: float, across_m: float = 0.0) -> bool:
        """Turn the slice to ``heading_deg`` about the vehicle: a new slice through the body (moved
        ``across_m`` to the right of the old slice first: a vehicle that slid sideways), the
        physics handed the surface under it along the new heading. Only while airborne and clear
        of that surface (a turning vehicle's feet would sweep through it); False: not turned (the
        world unchanged)."""
        if stepper.in_contact():
            return False
        _t, x, z = stepper.motion()[:3]
        xw, zw = x + self.ox, z + self.oz
        n, e = self.ne(xw)
        if across_m:
            c, s = self._dir()
            n, e = n - across_m * s, e + across_m * c
        old = (self.heading_deg, self.n0, self.e0)
        self.heading_deg, self.n0, self.e0 = heading_deg % 360.0, n, e
        roof, slope, x0, z0 = self.surface_under(0.0)
        a = math.radians(slope)
        if -x0 * math.sin(a) + (zw - z0) * math.cos(a) < CLEAR_M:
            self.heading_deg, self.n0, self.e0 = old
            return False
        # the body is at 0 along the new slice: in the new model frame at (-x0, zw - z0)
        stepper.set_slope(slope, x + x0, z - (zw - z0))
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
        fall_azimuth_deg=scenario.fall_azimuth_deg,
    )
    if scenario.start_on == "roof":  # facing north, the roof's section along north under it
        _roof, slope, x0, z0 = world.surface_under(scenario.start_x)
        stepper.set_slope(slope, x0, z0)
        world.ox, world.oz, world.on_roof = x0, z0, True
    stepper.place(height=0.0, x=scenario.start_x - world.ox)
    stepper.step(0.5, 0.0, 0.0)  # settle on the ground
    return stepper, world
