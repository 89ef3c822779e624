"""RESET: the legs' springs only return them to their rest angle once the friction is let go."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State, hand_to_loiter
from slopelander.controller.states.takeoff import height_over_roof

#: While the legs loosen the vehicle hovers in GUIDED, which holds the autopilot's height estimate,
#: not the height over the roof. An estimate upset on the roof (soak on ArduCopter at ea848b5,
#: landing 135: a 5 g, 31 ms accelerometer spike while the vehicle stood on a 9 deg roof) sank the
#: vehicle from 1.65 m to 0.25 m over the roof in the 8 s the legs took, and on to 0.10 m after
#: READY, motors at hover. So the range is watched: a height over the roof (read as TAKEOFF reads
#: it) below the clear height less SINK_M climbs at CLIMB_MPS, re-sent every RESEND_S, until the
#: clear height is read again.
SINK_M = 0.2
CLIMB_MPS = 0.5
RESEND_S = 0.1
#: READY needs the height held: no reading under the clear height less SINK_M for this long.
#: Not held by ``legs.ready_timeout_s`` after RESET began: handed to LOITER with the reason.
HELD_S = 1.0


class Reset(State):
    """Loosens every leg and waits for the board to report them loose, holding the vehicle's height
    over the roof by the range meanwhile (:data:`SINK_M`). Legs that do not loosen (a fault, no
    report in time, no board) are not a vehicle ready for the next landing: the vehicle is handed
    to the autopilot's LOITER rather than left hovering in GUIDED with nobody sending it anything,
    and the landing ends READY with the reason, for the pilot (the next landing's CHECKS refuses
    LOITER: switching back to GUIDED is the pilot's decision)."""

    name = "RESET"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        ctx.act.loosen_legs()
        ctx.marks["reset_low_t"] = None  # the last reading under the clear height less SINK_M
        ctx.marks["reset_climb_t"] = None  # the last climb setpoint sent
        return None

    def _guard(self, ctx: Context, inp: Inputs) -> None:
        """Climb while the range reads the vehicle sunk toward the roof; hold once clear again."""
        m, clear = ctx.marks, ctx.cfg["takeoff.clear_height_m"]
        h = height_over_roof(ctx, inp)
        if h is None:
            return
        if h < clear - SINK_M:
            if m["reset_climb_t"] is None:
                ctx.act.statustext(f"SL reset: {h:.2f} m over the roof, climbing"[:50])
            m["reset_low_t"] = inp.t
        if m["reset_climb_t"] is not None and h >= clear:
            ctx.act.hold(0.0)  # the climb target replaced by a hold, not left to GUID_TIMEOUT
            m["reset_climb_t"] = None
        elif (m["reset_low_t"] == inp.t and m["reset_climb_t"] is None) or (
            m["reset_climb_t"] is not None and inp.t - m["reset_climb_t"] >= RESEND_S
        ):
            ctx.act.hold(CLIMB_MPS)
            m["reset_climb_t"] = inp.t

    def _held(self, ctx: Context, inp: Inputs) -> bool:
        low = ctx.marks.get("reset_low_t")
        return ctx.marks.get("reset_climb_t") is None and (low is None or inp.t - low >= HELD_S)

    def step(self, ctx: Context, inp: Inputs):
        # the inputs of the step that entered RESET still describe the preset before it
        if inp.t <= ctx.entered_at:
            return None
        self._guard(ctx, inp)
        if inp.legs_fault is not None:
            hand_to_loiter(ctx, inp)
            return ("READY", f"legs did not loosen: {inp.legs_fault}; handed to LOITER")
        if inp.legs_ready and self._held(ctx, inp):
            return ("READY", "legs loosened: the springs reset them")
        if inp.t - ctx.entered_at > ctx.cfg["legs.ready_timeout_s"]:
            hand_to_loiter(ctx, inp)
            if inp.legs_ready:
                return ("READY", "legs loosened but the height over the roof not held: handed to LOITER")
            return ("READY", "legs did not report loose in time: handed to LOITER, check them before landing")
        return None
