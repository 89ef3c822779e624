"""CHECKS: everything the landing relies on, verified once before the descent starts."""

from __future__ import annotations

from slopelander.controller.link import stream_refusal
from slopelander.controller.script_rules import FAULT_REFUSAL, faulted
from slopelander.controller.slope_estimate import pilot_refusal
from slopelander.controller.states.aborted import abort_rising
from slopelander.controller.states.base import SCRIPT_CONTRACT, Context, Inputs, State
from slopelander.controller.states.settled import reads_near_the_roof


def refusal(inp: Inputs) -> str | None:
    """The first failed pre-descent check, or None."""
    if not inp.script_present:
        return "on-board script not present"
    if faulted(inp.script_state, inp.script_present):
        return FAULT_REFUSAL
    if inp.script_version is None:
        return "on-board script did not report its version (SL_VER)"
    if inp.script_version < SCRIPT_CONTRACT:
        # an older script would take the arm but end the reverse thrust its own way
        return (
            f"on-board script v{inp.script_version:g}, v{SCRIPT_CONTRACT} needed: "
            "install firmware_params/scripts/slopelander.lua"
        )
    if not inp.range_valid:
        return "rangefinder not healthy"
    if not inp.legs_ready:
        return "legs not ready"
    if inp.speed_mps is None:
        return "no velocity (LOCAL_POSITION_NED): rest could not be told from a slide"
    if inp.mode != "GUIDED":
        return f"mode {inp.mode}, GUIDED needed"
    if not inp.armed:
        return "vehicle not armed"
    return None


def angle_refusal(ctx: Context, inp: Inputs) -> str | None:
    """Why the uphill legs' reported angle does not fit the preset's, or None."""
    want = ctx.uphill_angle_deg
    if want is None:
        return None
    if not inp.uphill_angles_deg:
        return "uphill leg angles not reported"
    worst = max(inp.uphill_angles_deg, key=lambda a: abs(a - want))
    if abs(worst - want) > ctx.cfg["legs.angle_tolerance_deg"]:
        return f"uphill legs at {worst:.1f} deg, preset needs {want:.1f} deg"
    return None


#: the downhill legs' angle every preset assumes (deg below the horizontal: fully extended, the
#: model's and the lookup table's ``angle_down_deg``); only the uphill angle is ever set
DOWNHILL_REST_DEG = 37.5


def downhill_refusal(ctx: Context, inp: Inputs) -> str | None:
    """Why the downhill legs are not at their rest angle, or None: legs that did not spring back
    after the last landing's reset land on a preset that assumed them extended."""
    if not inp.downhill_angles_deg:
        return None  # a machine stepped without a board's report (the bench): nothing to compare
    worst = max(inp.downhill_angles_deg, key=lambda a: abs(a - DOWNHILL_REST_DEG))
    if abs(worst - DOWNHILL_REST_DEG) > ctx.cfg["legs.angle_tolerance_deg"]:
        return (
            f"downhill legs at {worst:.1f} deg, every preset assumes {DOWNHILL_REST_DEG:g} deg (not reset?)"
        )
    return None


def slope_refusal(ctx: Context, inp: Inputs) -> str | None:
    """Why the landing's slope (the pilot's number, or the measured one) does not fit the
    measurement, naming both, or None; nothing to check when the slope was not measured."""
    est = inp.slope_measured
    if est is None:
        return None
    if ctx.slope_deg is None or inp.slope_bound_deg is None:
        return "slope measured but the landing's slope or the bound is unknown"
    return pilot_refusal(ctx.slope_deg, est, inp.slope_bound_deg)


class Checks(State):
    name = "CHECKS"

    def step(self, ctx: Context, inp: Inputs):
        low = reads_near_the_roof(ctx.cfg, inp)
        if low is not None:
            return abort_rising(ctx, f"check failed: {low}")
        why = refusal(inp) or angle_refusal(ctx, inp) or downhill_refusal(ctx, inp) or slope_refusal(ctx, inp)
        # the streams the landing reads deliver at least link.min_delivered_fraction of their rate
        why = why or stream_refusal(getattr(ctx.act, "link", None), ctx.cfg["link.min_delivered_fraction"])
        if why is not None:
            return ("ABORTED", f"check failed: {why}")
        return ("DESCEND", "checks passed")
