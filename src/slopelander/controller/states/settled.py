"""SETTLED: the stock land detector is slow and may never fire on a slope, so the companion disarms,
but only a vehicle at rest: one sliding at a steady speed reads 1 g like one standing still."""

from __future__ import annotations

import math

from slopelander.controller.states.base import Context, Inputs, State, keep_reflex, still
from slopelander.controller.states.reverse import SCRIPT_RVT


def _moved(ctx: Context, inp: Inputs) -> float | None:
    """Distance (m) from where the vehicle was when SETTLED began (None: position unknown)."""
    if inp.position_m is None:
        return None
    start = ctx.marks.setdefault("settle_pos", inp.position_m)
    return math.dist(start, inp.position_m)


class Settled(State):
    """Disarms once the vehicle has been still (:func:`still`: accel 1 g and speed low) for
    ``settle.still_s``. A slide (faster than ``settle.slide_speed_mps`` and more than
    ``settle.slide_m`` from where SETTLED began) is not disarmed: the landing is aborted to the
    pilot, armed, in LOITER (docs/failsafes.md)."""

    name = "SETTLED"
    reflex_owns = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.marks.pop("still_since", None)
        ctx.marks.pop("settle_pos", None)
        _moved(ctx, inp)
        return None

    def step(self, ctx: Context, inp: Inputs):
        cfg = ctx.cfg
        speed, moved = inp.speed_mps, _moved(ctx, inp)
        fast = speed is not None and speed > cfg["settle.slide_speed_mps"]
        if fast and moved is not None and moved > cfg["settle.slide_m"]:
            return (
                "ABORTED",
                f"sliding at {speed:.2f} m/s, {moved:.2f} m after reverse thrust: not disarmed",
            )
        keep_reflex(ctx, inp, thrust_ended=True)  # SETTLED comes after the thrust
        if still(cfg, inp):
            since = ctx.marks.setdefault("still_since", inp.t)
            # not while the script still ramps the reverse thrust down: the legs are unbending
            if inp.t - since >= cfg["settle.still_s"] and inp.script_state != SCRIPT_RVT:
                ctx.act.disarm()
                return ("LANDED", "still: motors stopped, disarming")
        else:
            ctx.marks.pop("still_since", None)
        if inp.t - ctx.entered_at >= cfg["settle.timeout_s"]:
            if speed is None:
                return ("ABORTED", "speed unknown within the settle timeout: not disarmed")
            if speed > cfg["settle.slide_speed_mps"]:
                return ("ABORTED", f"still moving at {speed:.2f} m/s at the settle timeout: not disarmed")
            # not moving but the accelerometer keeps shaking (a vibrating sensor): the motors
            # are stopped either way, and it must not stay armed for ever
            ctx.act.disarm()
            return ("LANDED", "not still within the settle timeout but not moving: disarming anyway")
        return None
