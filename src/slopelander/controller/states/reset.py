"""RESET: the legs' springs only return them to their rest angle once the friction is let go."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State, hand_to_loiter


class Reset(State):
    """Loosens every leg and waits for the board to report them loose. Legs that do not loosen
    (a fault, no report in time, no board) are not a vehicle ready for the next landing: the
    vehicle is handed to the autopilot's LOITER (ABORTED) and the pilot told, rather than left
    hovering in GUIDED with nobody sending it anything: it is handed to the autopilot's LOITER
    and the landing ends READY with the reason, for the pilot (the next landing's CHECKS refuses
    LOITER: switching back to GUIDED is the pilot's decision)."""

    name = "RESET"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.loosen_legs()
        return None

    def step(self, ctx: Context, inp: Inputs):
        # the inputs of the step that entered RESET still describe the preset before it
        if inp.t <= ctx.entered_at:
            return None
        if inp.legs_fault is not None:
            hand_to_loiter(ctx, inp)
            return ("READY", f"legs did not loosen: {inp.legs_fault}; handed to LOITER")
        if inp.legs_ready:
            return ("READY", "legs loosened: the springs reset them")
        if inp.t - ctx.entered_at > ctx.cfg["legs.ready_timeout_s"]:
            hand_to_loiter(ctx, inp)
            return ("READY", "legs did not report loose in time: handed to LOITER, check them before landing")
        return None
