"""REVERSE: reverse thrust presses the vehicle onto the slope so it neither slides nor flips.

A fixed duration is wrong both ways: above atan(mu_k) (38.7 deg for the paper's feet) a vehicle
still sliding when the thrust stops keeps sliding, while one at rest stays there up to
atan(mu_s) (50 deg). So the thrust lasts at least ``reflex.reverse_thrust_ms``, then ends as soon
as the vehicle has read still (accel and speed, :func:`still`) for ``reflex.reverse_still_s``, and
at the latest after ``reflex.reverse_max_ms``, the bound the script itself keeps. The script
ramps the thrust down over ``reflex.reverse_ramp_ms`` when it ends: the legs, bent under it,
must spring back slowly for the feet to hold (docs/model.md).
"""

from __future__ import annotations

from slopelander.controller.script_contract import ScriptState
from slopelander.controller.states.base import Context, Inputs, State, keep_reflex, still

#: how long past its longest duration the script may still report reverse thrust before the
#: companion stops waiting for it (the script's own bound is the duration plus a tick)
REVERSE_OVERRUN_S = 1.0
SCRIPT_RVT = ScriptState.RVT


class Reverse(State):
    """Ends on evidence of rest, or when the script's bounded reverse phase ends."""

    name = "REVERSE"
    reflex_owns = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.marks.pop("rvt_still_since", None)
        return None

    def step(self, ctx: Context, inp: Inputs):
        cfg = ctx.cfg
        elapsed = inp.t - ctx.entered_at
        shortest = cfg["reflex.reverse_thrust_ms"] / 1000.0
        longest = (cfg["reflex.reverse_max_ms"] + cfg["reflex.reverse_ramp_ms"]) / 1000.0
        if still(cfg, inp):
            since = ctx.marks.setdefault("rvt_still_since", inp.t)
        else:
            ctx.marks.pop("rvt_still_since", None)
            since = None
        if elapsed >= shortest and since is not None and inp.t - since >= cfg["reflex.reverse_still_s"]:
            ctx.act.reflex_end_reverse()
            ctx.marks["reflex_sent"] = inp.t  # the end is a refresh too
            return ("SETTLED", f"still under reverse thrust after {elapsed:.2f} s: thrust ended")
        if elapsed >= shortest and inp.script_state != SCRIPT_RVT:
            return ("SETTLED", f"reverse thrust ended by the script after {elapsed:.2f} s")
        keep_reflex(ctx, inp)
        if elapsed >= longest + REVERSE_OVERRUN_S:
            # the script did not end its bounded reverse phase: nothing to take back (from the cut
            # on it refuses a release, and a release on the roof is what the landing avoids);
            # SETTLED asks for the disarm once the vehicle is still
            return ("SETTLED", "script still reversing after its duration")
        return None
