"""SETTLED: the stock land detector is slow and may never fire on a slope, so the companion disarms,
but only a vehicle at rest: one sliding at a steady speed reads 1 g like one standing still."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State, keep_reflex, still


class Settled(State):
    """Disarms once the vehicle has been still (:func:`still`: accel 1 g and speed low) for
    ``settle.still_s``. A slide (speed above ``settle.slide_speed_mps``) is not disarmed: the
    landing is aborted to the pilot, armed, in LOITER (docs/failsafes.md)."""

    name = "SETTLED"
    reflex_owns = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.marks.pop("still_since", None)
        return None

    def step(self, ctx: Context, inp: Inputs):
        cfg = ctx.cfg
        speed = inp.speed_mps
        if speed is not None and speed > cfg["settle.slide_speed_mps"]:
            return ("ABORTED", f"sliding at {speed:.2f} m/s after reverse thrust: not disarmed")
        keep_reflex(ctx, inp)
        if still(cfg, inp):
            since = ctx.marks.setdefault("still_since", inp.t)
            if inp.t - since >= cfg["settle.still_s"]:
                ctx.act.disarm()
                return ("LANDED", "still: motors stopped, disarming")
        else:
            ctx.marks.pop("still_since", None)
        if inp.t - ctx.entered_at >= cfg["settle.timeout_s"]:
            if speed is None:
                return ("ABORTED", "speed unknown within the settle timeout: not disarmed")
            # not moving but the accelerometer keeps shaking (a vibrating sensor): the motors
            # are stopped either way, and it must not stay armed for ever
            ctx.act.disarm()
            return ("LANDED", "not still within the settle timeout but not moving: disarming anyway")
        return None
