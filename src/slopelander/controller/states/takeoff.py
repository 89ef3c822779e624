"""TAKEOFF: the legs stay clamped until the vehicle is clear, or a leg could drop onto the slope."""

from __future__ import annotations

import math

from slopelander.controller.roof import rise_over_roof, roof_plane
from slopelander.controller.script_rules import FAULT_REFUSAL, faulted
from slopelander.controller.states.base import Context, Inputs, State, hand_to_loiter

#: a reading is believed only when it follows the last believed one within this jump plus what the
#: fastest climb covers since the previous valid reading: a spike on the ground is not a climb
JUMP_M = 0.1
MAX_CLIMB_MPS = 8.0  # with the slant of a body still tilting level after leaving the roof
#: the believed range stays at or above the clear height this long before the legs loosen
HOLD_S = 0.25
#: readings that disagree with the believed one for this long start a new chain (the sensor came
#: back after a dropout during the climb); the hold then starts again
RESEED_S = 1.0
#: no believed clear range within this (vehicle time): a vehicle that climbed is handed to the
#: autopilot's LOITER with the legs left clamped (safe in the air; READY, the pilot told); one that
#: never left the roof is disarmed there (LANDED), not left idling armed on it
GIVE_UP_S = 15.0
#: the vehicle rose at least this much (m) over the roof (:func:`rise_over_roof`) since the take-off
#: was asked: it flew
CLIMBED_M = 0.3
#: the autopilot refused the companion's disarm this long after GIVE_UP_S (its land detector says
#: the vehicle flies): the vehicle is handed to LOITER, legs clamped, rather than asked for ever
DISARM_REFUSED_S = 10.0
#: how far (m) the rise over the roof (:func:`rise_over_roof`) may fall short of the
#: clear height when a clear range is believed: its height estimate's error over a take-off's few
#: seconds. The body's rest height over the roof is not counted (no reading on the roof need be
#: valid: the soak's first valid reading was a spike of 2.42 m with the body 0.07 m up, 0.25 s long,
#: and loosened the legs): a body resting high loosens its legs that much later, within the climb
#: to the take-off's target (twice the clear height)
CLIMB_TOLERANCE_M = 0.15
#: vehicle seconds between asks for the disarm of a vehicle that never left the roof
DISARM_RETRY_S = 1.0
#: not armed this long after the take-off was asked (vehicle time): the autopilot refuses to arm
#: (ArduCopter: the pilot's throttle stick not at the bottom, AP_Arming::rc_arm_checks): back to
#: LANDED, disarmed on the roof, legs clamped; the arm is asked again every ARM_RETRY_S meanwhile
ARM_WAIT_S = 10.0
ARM_RETRY_S = 1.0


def takeoff_altitude(ctx: Context, inp: Inputs) -> float:
    """The NAV_TAKEOFF altitude (m): a climb of twice ``takeoff.clear_height_m`` over where the
    vehicle is. ArduCopter takes it above home (the parameter files' ``WPNAV_RFND_USE 0``), and
    home is where the vehicle last armed (AP_Arming_Copter::arm): a disarmed vehicle, armed by the
    take-off, is at home; an armed one (a take-off from the held landing) adds its height above
    home (GLOBAL_POSITION_INT), without which a roof higher than the climb over the pad it armed on
    made the command "downwards" and refused."""
    climb = ctx.cfg["takeoff.clear_height_m"] * 2
    if inp.armed and inp.above_home_m is not None and math.isfinite(inp.above_home_m):
        return climb + inp.above_home_m
    return climb


def height_over_slope(range_m: float, tilt_deg: float, slope_deg: float) -> float:
    """The height (m) of the body over the slope below it that a reading of ``range_m`` along a body
    tilted ``tilt_deg`` from level guarantees. The tilt is taken downhill, where the beam reads
    longest: ``range * cos(slope + tilt) / cos(slope)`` (a 10 deg tilt over a 44 deg roof reads
    1.22 times the height, so a reading of 0.8 m there guarantees only 0.65 m). 0 when the beam
    could run along the slope, or when a number is not finite (never "clear" by accident)."""
    a, t = math.radians(slope_deg), math.radians(tilt_deg)
    c = math.cos(a + t)
    if not c > 0.05:  # also NaN
        return 0.0
    return range_m * c / math.cos(a)


def landing_slope(ctx: Context) -> float:
    """The slope (deg) a range is read over: the landing's, else ``takeoff.unknown_slope_deg``."""
    return ctx.slope_deg if ctx.slope_deg is not None else ctx.cfg["takeoff.unknown_slope_deg"]


def height_over_roof(ctx: Context, inp: Inputs) -> float | None:
    """The height over the roof a valid reading taken with the body level (within
    ``takeoff.max_tilt_deg``) guarantees (:func:`height_over_slope`, over :func:`landing_slope`),
    or None: no valid reading, or the body too tilted for the beam to say."""
    if not inp.range_valid or inp.tilt_deg is None or inp.tilt_deg > ctx.cfg["takeoff.max_tilt_deg"]:
        return None
    return height_over_slope(inp.range_m, inp.tilt_deg, landing_slope(ctx))


def roof_of(ctx: Context, inp: Inputs) -> tuple[float | None, float | None, float | None]:
    """The roof the take-off leaves (:func:`~slopelander.controller.roof.roof_plane`): the
    survey's plane, else the landing's slope along the heading the vehicle had when the take-off
    began (it lands facing the way the roof falls); else unknown."""
    return roof_plane(inp.slope_measured, ctx.slope_deg, ctx.marks.get("takeoff_heading"))


class Takeoff(State):
    """Releases the script, takes off, and moves on once the range shows the vehicle clear: a
    chain of readings that each follow the last (no spike, no jump) above the clear height for
    ``HOLD_S`` (found by the soak benchmark: one spike on the ground loosened the legs), each read
    with the body within ``takeoff.max_tilt_deg`` of level. The rangefinder points along the
    body: leaving a 40 deg roof the body swings 20-25 deg the other way, and the tilted beam then
    reads up to 1.5 times the height over the slope (found by the soak: legs loosened 0.66-0.84 m
    above the roof on readings of 0.84-1.14 m). The attitude is the one of the reading's own
    moment; none is not level. Within the tilt allowed, the reading is still turned into a height
    over the slope (:func:`height_over_slope`) before it is compared with the clear height. And a
    clear range is believed only with the climb LOCAL_POSITION_NED reports since the take-off
    began bearing it out (:meth:`_climb_short`): the soak on ArduCopter loosened the legs on a
    0.25 s spike of 2.42 m with the body 0.07 m over the roof."""

    name = "TAKEOFF"
    #: a refused take-off leaves the vehicle where it was: disarmed on the roof
    refused_to = "LANDED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        if faulted(inp.script_state, inp.script_present):
            return FAULT_REFUSAL  # nothing armed or released: see Landed
        ctx.act.release_for_takeoff()  # a held, armed vehicle is given back only level enough
        ctx.marks.pop("impact", None)  # the landing is over: the next one meets its roof anew
        ctx.act.takeoff(takeoff_altitude(ctx, inp))
        ctx.marks["takeoff_range"] = None  # (t, m) of the last believed reading
        ctx.marks["takeoff_disagree"] = None  # since when readings disagree with it
        ctx.marks["takeoff_clear"] = None  # since when the believed range is clear
        ctx.marks["takeoff_sent"] = inp.t
        ctx.marks["takeoff_prev_t"] = None  # time of the previous valid reading, believed or not
        ctx.marks["takeoff_short_said"] = None
        if ctx.previous == "LINK_LOST" and ctx.marks.get("takeoff_p0") is not None:
            return None  # the same take-off goes on: its climb is counted from where it began
        ctx.marks["takeoff_p0"] = inp.position_m
        ctx.marks["takeoff_heading"] = inp.heading_deg
        ctx.marks["takeoff_rose"] = False
        return None

    @staticmethod
    def _rise(ctx: Context, inp: Inputs) -> float | None:
        """The rise over the roof since the take-off began (:func:`rise_over_roof`), None without
        a position."""
        p0 = ctx.marks.get("takeoff_p0")
        if inp.position_m is None or p0 is None:
            return None
        return rise_over_roof(p0, inp.position_m, *roof_of(ctx, inp))

    @classmethod
    def _climb_short(cls, ctx: Context, inp: Inputs) -> str | None:
        """Why the vehicle's own climb over the roof since the take-off began does not bear out a
        clear range, or None: it must have risen the clear height, less
        :data:`CLIMB_TOLERANCE_M`."""
        need = ctx.cfg["takeoff.clear_height_m"] - CLIMB_TOLERANCE_M
        rise = cls._rise(ctx, inp)
        if rise is None:
            return "no position (LOCAL_POSITION_NED) to confirm the climb"
        if rise < need:
            return f"climbed {rise:.2f} m of {need:.2f} m"
        return None

    @classmethod
    def _rose(cls, ctx: Context, inp: Inputs) -> bool:
        """Whether the vehicle has left the roof: it rose :data:`CLIMBED_M` over the roof from the
        first position known in TAKEOFF (once seen, remembered). With no position ever known it
        cannot be told, and is taken to have flown (the legs then stay clamped, handed to LOITER)."""
        m = ctx.marks
        if m.get("takeoff_heading") is None:
            m["takeoff_heading"] = inp.heading_deg  # the first known: still the landing's
        if inp.position_m is not None:
            if m.get("takeoff_p0") is None:
                m["takeoff_p0"] = inp.position_m
            if cls._rise(ctx, inp) >= CLIMBED_M:
                m["takeoff_rose"] = True
        return m["takeoff_rose"] or m.get("takeoff_p0") is None

    def step(self, ctx: Context, inp: Inputs):
        m = ctx.marks
        if not inp.armed and m.get("takeoff_disarm_sent") is not None:
            return ("LANDED", f"take-off failed: no climb within {GIVE_UP_S:g} s; disarmed on the roof")
        if not inp.armed:
            waited = inp.t - ctx.entered_at
            if waited > ARM_WAIT_S:
                return (
                    "LANDED",
                    f"take-off refused: not armed within {ARM_WAIT_S:g} s (the autopilot refuses to arm: "
                    "on ArduCopter the pilot's throttle stick must be at the bottom)",
                )
            if ctx.act.refused("arm") and inp.t - m.get("takeoff_sent", -1.0) >= ARM_RETRY_S:
                m["takeoff_sent"] = inp.t  # refused (a stick up, a pre-arm check): ask again
                ctx.act.takeoff(takeoff_altitude(ctx, inp))
            # the readings below still seed the chain: the ground, before any spike
        rose = self._rose(ctx, inp)
        if inp.t - ctx.entered_at > GIVE_UP_S:
            if rose:
                hand_to_loiter(ctx, inp)
                return (
                    "READY",
                    f"legs left clamped: no trustworthy clear range within {GIVE_UP_S:g} s; "
                    "handed to LOITER, loosen them by hand after landing",
                )
            if not inp.armed:
                return (
                    "LANDED",
                    f"take-off failed: never climbed within {GIVE_UP_S:g} s; disarmed on the roof",
                )
            if inp.t - ctx.entered_at > GIVE_UP_S + DISARM_REFUSED_S and ctx.act.refused("disarm_on_ground"):
                hand_to_loiter(ctx, inp)
                return (
                    "READY",
                    f"legs left clamped: no climb seen within {GIVE_UP_S:g} s and the autopilot refuses "
                    "to disarm (its land detector says flying); handed to LOITER",
                )
            if inp.t - m.get("takeoff_disarm_sent", -1e9) >= DISARM_RETRY_S:
                m["takeoff_disarm_sent"] = inp.t  # armed on the roof and not flying: disarm it there
                ctx.act.disarm_on_ground()
                ctx.act.statustext(f"SL take-off: no climb in {GIVE_UP_S:g} s, disarming")
            return None
        if inp.armed and ctx.act.refused("takeoff") and inp.t - m.get("takeoff_sent", -1.0) >= 1.0:
            # on a lossy link the take-off can arrive before the arm (or the mode) and be refused
            # (found by the soak: armed on the roof, never climbing): send it again, armed now
            m["takeoff_sent"] = inp.t
            ctx.act.takeoff(takeoff_altitude(ctx, inp))
        last = m.get("takeoff_range")
        # a stale or invalid reading must never loosen the legs on the ground (nor one beyond the
        # sensor's reach: a vehicle that climbs out of it first ends by GIVE_UP_S, legs clamped)
        if not inp.range_valid:
            return None
        # the allowance grows only over time without any valid reading (a dropout), not while
        # readings keep coming and disagree (a spike that lasts)
        prev_t = m.get("takeoff_prev_t")
        m["takeoff_prev_t"] = inp.t
        gap = inp.t - prev_t if prev_t is not None else 0.0
        if last is not None and abs(inp.range_m - last[1]) > JUMP_M + MAX_CLIMB_MPS * gap:
            if m.get("takeoff_disagree") is None:
                m["takeoff_disagree"] = inp.t
            if inp.t - m["takeoff_disagree"] < RESEED_S:
                m["takeoff_clear"] = None
                return None
            m["takeoff_clear"] = None  # a new chain: the hold starts again
        m["takeoff_disagree"] = None
        m["takeoff_range"] = (inp.t, inp.range_m)
        cfg = ctx.cfg
        height = height_over_roof(ctx, inp)
        if height is None or height < cfg["takeoff.clear_height_m"]:
            m["takeoff_clear"] = None
            return None
        if m.get("takeoff_clear") is None:
            m["takeoff_clear"] = inp.t
        if inp.t - m["takeoff_clear"] >= HOLD_S:
            # the range alone is not believed: the vehicle's own climb must bear it out
            short = self._climb_short(ctx, inp)
            if short is not None:
                if m.get("takeoff_short_said") is None:
                    m["takeoff_short_said"] = inp.t
                    ctx.act.statustext(f"SL range clear, not climbed: {short}"[:50])
                return None
            rise = self._rise(ctx, inp)
            return (
                "RESET",
                f"clear of the ground at {height:.2f} m over the {landing_slope(ctx):g} deg slope "
                f"(range {inp.range_m:.2f} m, tilt {inp.tilt_deg:.0f} deg, climbed {rise:.2f} m)",
            )
        return None
