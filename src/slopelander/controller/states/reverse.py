"""REVERSE: reverse thrust presses the vehicle onto the slope so it neither slides nor flips."""

from __future__ import annotations

from slopelander.controller.states.base import Context, Inputs, State

#: how long past its configured duration the script may still report reverse thrust before the
#: companion releases the outputs itself (the script's own bound is the duration plus a tick)
REVERSE_OVERRUN_S = 1.0


class Reverse(State):
    """Lasts the configured reverse-thrust time and until the script has left its reverse phase."""

    name = "REVERSE"
    reflex_owns = True

    def step(self, ctx: Context, inp: Inputs):
        elapsed = inp.t - ctx.entered_at
        done = elapsed >= ctx.cfg["reflex.reverse_thrust_ms"] / 1000.0
        if done and inp.script_state != 12:
            return ("SETTLED", "reverse thrust done")
        if elapsed >= ctx.cfg["reflex.reverse_thrust_ms"] / 1000.0 + REVERSE_OVERRUN_S:
            ctx.act.release()  # the script did not end its bounded reverse phase: take it back
            return ("SETTLED", "script still reversing after its duration: released")
        return None
