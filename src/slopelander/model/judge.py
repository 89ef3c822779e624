"""Judge a landing flown step by step (a simulated vehicle's Stepper) as ``simulate`` judges one.

A flying vehicle's Stepper has been in contact before (it took off from somewhere), so its
landing bookkeeping is reset while it is in the air; its first contact then starts a landing
that is classified with the model's own criteria and classifier (``kernel.classify``), and the
conditions at that contact are recorded as :class:`LandingConditions`, so that ``simulate`` can
replay the same landing from the same inputs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slopelander.model import kernel as k
from slopelander.model.conditions import LandingConditions
from slopelander.model.landing import LandingResult
from slopelander.model.stepper import Stepper

AIRBORNE_CLEARANCE_M = 0.05  # lowest point this far clear of the surface: a new landing may start
CHECK_EVERY = 4  # physics steps between clearance checks while no landing is expected


@dataclass(frozen=True)
class Impact:
    """The vehicle just before its first contact: what ``LandingConditions`` holds, plus the
    rotors' state, which a landing in ``simulate`` starts from zero."""

    t: float
    slope_deg: float
    vz: float  # m/s, z up (negative: descending)
    vx: float
    pitch_deg: float
    pitch_rate_dps: float
    tau_up: float  # N*m per real joint
    tau_down: float
    angle_up_deg: float  # friction-joint angles (deg)
    angle_down_deg: float
    leg_up_deg: float  # leg angles (deg): equal to the joint's while the leg is unloaded
    leg_down_deg: float
    rotor_speed: tuple[float, float]  # (rear/-x, front/+x), signed fraction of full
    rotor_thrust: tuple[float, float]  # N


@dataclass(frozen=True)
class ThrustProfile:
    """What the rotors were commanded from first contact to the decision."""

    reverse_percent: float  # the first reverse command, percent of the full reverse rotor command (0: none)
    reverse_delay: float  # s from first contact to that command (NaN: none)
    reverse_changed: bool  # the reverse command changed or ended before the decision
    forward_after_contact: float  # the largest forward command after contact (0..1)


class LandingJudge:
    """Call :meth:`update` after every ``stepper.step``; :attr:`result` is set once decided."""

    def __init__(self, stepper: Stepper) -> None:
        self.st = stepper
        m = stepper.model
        self._p, self._fl, self._crit = m.params.as_array(), m.flags(), m.criteria_array()
        self.armed = False
        self.impact: Impact | None = None
        self.result: LandingResult | None = None
        self._prev: np.ndarray | None = None
        self._n = 0
        self._reset_profile()

    def _reset_profile(self) -> None:
        self._rev_cmd, self._rev_t, self._rev_changed, self._fwd = 0.0, math.nan, False, 0.0
        self._rest, self._slid = 0.0, False

    # -- the landing bookkeeping ----------------------------------------------------------
    def _rearm(self) -> None:
        """Forget earlier contacts: the next first contact starts a landing."""
        self.st.st[k.S_TIMP] = -1.0
        self.st.st[k.S_TOUCH] = 0.0
        self.armed, self.impact, self.result = True, None, None
        self._reset_profile()
        self._track()

    def _track(self) -> None:
        """In the air before a landing: bookkeeping as ``init_landing`` leaves it, at this state."""
        s, ctx = self.st.st, self.st.ctx
        s[k.S_QEMIN : k.S_QEMIN + 2] = s[k.S_QE : k.S_QE + 2]
        ctx[k.C_QINIT : k.C_QINIT + 2] = s[k.S_QE : k.S_QE + 2]
        s[k.S_PMIN] = s[k.S_PMAX] = s[k.S_Q + 2]
        s[k.S_NPEAK] = 0.0  # the landing's impact load, not one from before
        self._prev = s.copy()  # the state before the step that makes contact

    def update(self, h: float, u_left: float, u_right: float) -> bool:
        """After a step of ``h`` s with these rotor commands; True on the step that decided."""
        s, ctx = self.st.st, self.st.ctx
        if not self.armed:
            # is it well in the air (checked every few steps: the geometry costs more than a step)
            self._n += 1
            if self._n % CHECK_EVERY == 0 and self.st.clearance() > AIRBORNE_CLEARANCE_M:
                self._rearm()
            return False
        if s[k.S_TIMP] < 0.0:
            self._track()
            return False
        if self.impact is None:
            self.impact = self._impact(self._prev if self._prev is not None else s)
        u = 0.5 * (u_left + u_right)
        t = s[k.S_T] - h  # the command acted from the start of this step
        if u < 0.0 and self._rev_cmd == 0.0:
            self._rev_cmd, self._rev_t = u, max(t, s[k.S_TIMP])
        elif self._rev_cmd != 0.0 and abs(u - self._rev_cmd) > 1e-9:
            self._rev_changed = True
        self._fwd = max(self._fwd, u)
        sl = float(k._slide(ctx, s))
        self._slid = self._slid or abs(sl) > self._crit[k.R_SLIDE]
        self._rest = self._rest + h if k._at_rest(s, self._crit) else 0.0
        settled = self._rest >= self._crit[k.R_SETTLE]
        flip = max(-s[k.S_PMIN], s[k.S_PMAX]) > self._crit[k.R_FLIP] * k.DEG
        over = s[k.S_T] - s[k.S_TIMP] >= self._crit[k.R_HORIZON]
        if not (settled or flip or self._slid or over):
            return False
        res = np.zeros(k.N_RESULT)
        k.classify(self._p, self._fl, ctx, s, self._crit, settled, self._slid, res)
        res[k.O_SLIDE] = sl
        res[k.O_TSETTLE] = s[k.S_T] - s[k.S_TIMP] - self._rest if settled else math.nan
        self.result = LandingResult.from_row(res)
        self.armed = False
        return True

    def _impact(self, s: np.ndarray) -> Impact:
        nj = self.st.model.params["joints_per_planar_leg"]
        j = int(self.st.ctx[k.C_DOWN])
        tau = self.st.ctx[k.C_TAU : k.C_TAU + 2] / nj
        deg = math.degrees
        return Impact(
            t=float(self.st.st[k.S_TIMP]),
            slope_deg=self.st.slope_deg,
            vz=float(s[k.S_V + 1]),
            vx=float(s[k.S_V]),
            pitch_deg=deg(s[k.S_Q + 2]),
            pitch_rate_dps=deg(s[k.S_V + 2]),
            tau_up=float(tau[1 - j]),
            tau_down=float(tau[j]),
            angle_up_deg=deg(s[k.S_QE + 1 - j]),
            angle_down_deg=deg(s[k.S_QE + j]),
            leg_up_deg=deg(s[k.S_Q + 4 - j]),
            leg_down_deg=deg(s[k.S_Q + 3 + j]),
            rotor_speed=(float(s[k.S_W]), float(s[k.S_W + 1])),
            rotor_thrust=(float(s[k.S_THR]), float(s[k.S_THR + 1])),
        )

    # -- what the model needs to replay it ------------------------------------------------
    @property
    def profile(self) -> ThrustProfile:
        t0 = self.impact.t if self.impact is not None else math.nan
        return ThrustProfile(
            reverse_percent=abs(100.0 * self._rev_cmd),
            reverse_delay=float(self._rev_t - t0) if self._rev_cmd != 0.0 else math.nan,
            reverse_changed=self._rev_changed,
            forward_after_contact=self._fwd,
        )

    def conditions(self) -> LandingConditions:
        """The landing as ``simulate`` takes it: slope, impact state, legs, thrust profile."""
        if self.impact is None:
            raise ValueError("no landing has begun")
        i, pr = self.impact, self.profile
        return LandingConditions(
            slope_deg=i.slope_deg,
            speed=-i.vz,
            horizontal_speed=i.vx,
            pitch_deg=i.pitch_deg,
            pitch_rate_dps=i.pitch_rate_dps,
            tau_up=i.tau_up,
            tau_down=i.tau_down,
            angle_up_deg=i.angle_up_deg,
            angle_down_deg=i.angle_down_deg,
            reverse_percent=pr.reverse_percent,
            reverse_delay=0.0 if math.isnan(pr.reverse_delay) else pr.reverse_delay,
        )
