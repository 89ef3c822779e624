"""SETTLED: the stock land detector is slow and may never fire on a slope, so the companion disarms."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State


class Settled(State):
    """Disarms once the accelerometer has read 1 g (within ``settle.still_mps2``) for ``settle.still_s``."""

    name = "SETTLED"
    reflex_owns = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.marks["still_since"] = inp.t
        return None

    def step(self, ctx: Context, inp: Inputs):
        if abs(inp.accel_mps2 - 9.80665) > ctx.cfg["settle.still_mps2"]:
            ctx.marks["still_since"] = inp.t
        if inp.t - ctx.marks["still_since"] >= ctx.cfg["settle.still_s"]:
            ctx.act.disarm()
            return ("LANDED", "still: motors stopped, disarming")
        if inp.t - ctx.entered_at >= ctx.cfg["settle.timeout_s"]:
            # the motors are stopped after reverse thrust either way; a vehicle that keeps
            # shaking (sliding, a vibrating sensor) must not stay armed for ever
            ctx.act.disarm()
            return ("LANDED", "not still within the settle timeout: disarming anyway")
        return None
