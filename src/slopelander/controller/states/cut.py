"""CUT: the motors are stopped and the vehicle falls; the script owns the motors until impact."""

from __future__ import annotations

from slopelander.controller.script_contract import FALL_WAIT_S, ScriptState, missed_impact_s
from slopelander.controller.states.base import Context, Inputs, State

#: the companion's backstop past the script's own missed-impact bound (s): two of the script's
#: 5 Hz SL_STATE announcements and a little, so a script that decided is heard before it
BACKSTOP_MARGIN_S = 0.5
#: a range this far above the cut height (m) says the vehicle is not on the roof
GROUND_MARGIN_M = 0.1


class Cut(State):
    """Watches for the impact (script or the companion's own IMU rule). The script judges a cut
    without impact itself, after the free fall from the cut height should have ended
    (:func:`missed_impact_s`): IDLE (a false cut, the motors given back) or HOLD (a soft
    contact, the motors held); a vehicle still falling freely there with the range near keeps
    its cut for up to :data:`FALL_WAIT_S` more, waiting for the impact. If its state is still CUT
    at the companion's backstop, past both (a stale or lost announcement), the range decides:
    near the roof the vehicle is judged as landed, motors held (SETTLED); higher, the landing is
    aborted to the autopilot."""

    name = "CUT"
    reflex_owns = True

    def step(self, ctx: Context, inp: Inputs):
        if inp.script_state in (ScriptState.RVT, ScriptState.HOLD) or inp.impact:
            ctx.marks["impact"] = inp.t
            return ("REVERSE", "impact")
        if inp.script_state == ScriptState.IDLE:
            return ("ABORTED", "script returned to IDLE after the cut: false cut, autopilot flies")
        cfg = ctx.cfg
        bound = missed_impact_s(cfg["reflex.cut_height_m"], cfg["descent.rate_mps"])
        bound += FALL_WAIT_S + BACKSTOP_MARGIN_S
        if inp.t - ctx.entered_at > bound:
            near = inp.range_valid and inp.range_m <= cfg["reflex.cut_height_m"] + GROUND_MARGIN_M
            if near:
                ctx.marks["impact"] = inp.t
                return ("SETTLED", f"no impact {bound:.2f} s after the cut, on the roof: motors held")
            return ("ABORTED", f"no impact {bound:.2f} s after the cut and not near the roof")
        return None
