"""SETTLED: the stock land detector is slow and may never fire on a slope, so the companion has the
vehicle disarmed, but only at rest (one sliding at a steady speed reads 1 g like one standing
still), and the landing ends only when the autopilot's HEARTBEAT says disarmed: a disarm sent is
not a disarm made (ArduCopter refuses a ground station's before its land detector fires)."""

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


#: how often (vehicle s) an unanswered or refused disarm request is sent again
DISARM_RETRY_S = 0.5


def request_disarm(ctx: Context, inp: Inputs) -> None:
    """Ask the on-board script to disarm (it does while it holds the motors stopped and the
    vehicle is still: docs/onboard-script.md), at most every :data:`DISARM_RETRY_S`."""
    if inp.t - ctx.marks.get("disarm_sent", -1e9) >= DISARM_RETRY_S:
        ctx.act.disarm()
        ctx.marks["disarm_sent"] = inp.t


class Settled(State):
    """Has the vehicle disarmed once it has been still (:func:`still`: accel 1 g and speed low)
    for ``settle.still_s``, and moves to LANDED when the HEARTBEAT shows it disarmed. A slide
    (faster than ``settle.slide_speed_mps`` and more than
    ``settle.slide_m`` from where SETTLED began) is not disarmed: the landing is aborted to the
    pilot, armed, in LOITER (docs/failsafes.md)."""

    name = "SETTLED"
    reflex_owns = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        for k in ("still_since", "settle_pos", "disarm_sent", "disarm_asked"):
            ctx.marks.pop(k, None)
        _moved(ctx, inp)
        return None

    def step(self, ctx: Context, inp: Inputs):
        cfg = ctx.cfg
        if not inp.armed:
            how = ctx.marks.get("disarm_asked", "by the autopilot")
            return ("LANDED", f"disarmed ({how}): seen in the HEARTBEAT")
        if "disarm_asked" in ctx.marks:  # asked: the motors stay held until the HEARTBEAT says so
            keep_reflex(ctx, inp, thrust_ended=True)
            request_disarm(ctx, inp)
            return None
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
                ctx.marks["disarm_asked"] = "still, motors held stopped"
                request_disarm(ctx, inp)
        else:
            ctx.marks.pop("still_since", None)
        if inp.t - ctx.entered_at >= cfg["settle.timeout_s"]:
            if speed is None:
                return ("ABORTED", "speed unknown within the settle timeout: not disarmed")
            if speed > cfg["settle.slide_speed_mps"]:
                return ("ABORTED", f"still moving at {speed:.2f} m/s at the settle timeout: not disarmed")
            # not moving but the accelerometer keeps shaking (a vibrating sensor): the motors
            # are stopped either way, and it must not stay armed for ever
            ctx.marks["disarm_asked"] = "not still within the settle timeout but not moving"
            request_disarm(ctx, inp)
        return None
