"""A slow, independent integration of the same equations: ``scipy.integrate.solve_ivp``.

The compiled kernel takes fixed semi-implicit steps and settles contact and joint modes inside
each step. This module integrates the same continuous equations with a stiff adaptive solver
(Radau) between mode changes, and finds every change as a root of an event function: a contact
starts or lets go, a foot sticks or slips, a joint sticks or slips, a joint enters the
end-of-travel zone or hits its stop, the vehicle flips. It shares only the kinematics (mass
matrix, Jacobians) with the kernel, so it checks the time stepping and the mode logic, and it
is what the speed benchmark compares against. Built-in effects only; no user effects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from slopelander.model import kernel as k
from slopelander.model.conditions import LandingConditions, conditions_array
from slopelander.model.landing import LandingResult, Model

DEG = math.pi / 180.0
# continuous state y: Q (5), V (5), q_E (2), rotor speed (2)
# the mode change that undoes each one
_UNDO = {
    "touch": "release",
    "release": "touch",
    "slip": "stick",
    "stick": "slip",
    "jslip": "jstick",
    "jstick": "jslip",
}


@dataclass
class _Modes:
    contact: np.ndarray  # per point: 0 off, 1 stuck, 2 slipping +t, 3 slipping -t
    anchor: np.ndarray
    joint: np.ndarray  # 0 stuck, -1 / +1 slipping


class ReferenceLanding:
    """One landing integrated event to event (see the module docstring)."""

    def __init__(self, model: Model, cond: LandingConditions, rtol: float = 1e-7, atol: float = 1e-9):
        if model.user_effects:
            raise ValueError("the reference integrator knows only built-in effects")
        cond.validate(model.params.angle_min_deg, model.params.angle_max_deg)
        self.model = model
        self.cond = cond
        self.p = model.params.as_array()
        self.fl = model.flags()
        self.rtol, self.atol = rtol, atol
        self.st = np.zeros(k.N_STATE)
        self.ctx = np.zeros(k.N_CTX)
        self.ws = k.make_workspace()
        row = conditions_array([cond]).view(np.float64).copy()
        k.init_landing(self.p, self.fl, row, self.st, self.ctx, self.ws)
        p, fl = self.p, self.fl
        self.rigid = fl[k.F_RIGID] != 0
        self.flex = fl[k.F_FLEX] != 0 and not self.rigid
        self.eot = fl[k.F_EOT] != 0
        self.q_end = (p[k.P_QMAX] - p[k.P_TRAVEL]) * DEG
        self.q_max = p[k.P_QMAX] * DEG
        self.q_zone = self.q_end + (p[k.P_EZ] * DEG if self.eot else 0.0)
        # normal law per contact point: the rigid gear's feet are its stiff, rebounding skids
        self.kg = np.full(k.N_POINTS, p[k.P_KG])
        self.bg = np.full(k.N_POINTS, p[k.P_BG])
        if self.rigid:
            self.kg[:2], self.bg[:2] = p[k.P_KR], p[k.P_BR]
        self.n_peak = 0.0  # largest normal force on a foot, sampled every 0.1 ms in contact
        self.kq = p[k.P_KQ] * p[k.P_NJ]
        self.bq = p[k.P_BQ] * p[k.P_NJ]
        self.ke = p[k.P_KE] if self.eot else 0.0
        self.be = p[k.P_BE] if self.eot else 0.0
        sa, ca = self.ctx[k.C_SIN], self.ctx[k.C_COS]
        self.n = np.array([sa, ca])
        self.tv = np.array([ca, -sa])
        dsg = 1.0 if sa >= 0.0 else -1.0
        self.downhill = dsg * self.tv
        self.down = int(self.ctx[k.C_DOWN])
        # the legs eqs. 3 and 4 act on, with each leg's outward sign along the surface tangent:
        # both by their condition, or the downhill one alone (the paper's reading; level: both)
        self._growing = [(0, -1.0), (1, 1.0)]
        if fl[k.F_PAPER_GROWTH] and sa != 0.0:
            self._growing = [self._growing[self.down]]
        self.modes = _Modes(np.zeros(k.N_POINTS), np.zeros(k.N_POINTS), np.zeros(2))
        self.t_impact: float | None = None
        self.touched = False
        self.qe_min = self.st[k.S_QE : k.S_QE + 2].copy()
        self.pitch_min = self.pitch_max = self.st[k.S_Q + 2]
        self.events = 0
        self.flipped = False
        self._last_key = None
        self._last: dict = {}
        # after a mode change, the change that would undo it waits this long (a slip that has
        # just begun has zero rate, and rounding must not decide it back at once)
        self._suppress: tuple | None = None
        self._suppress_until = -1.0

    # -- the continuous equations ----------------------------------------------------------------
    def _eval(self, t: float, y: np.ndarray) -> dict:
        """Everything the right-hand side and the event functions need, for the current modes
        (memoised: solve_ivp asks every event function about the same point)."""
        key = (t, y.tobytes(), self._mode_key)
        if key == self._last_key:
            return self._last
        self._last = self._compute(t, y)
        self._last_key = key
        return self._last

    @property
    def _mode_key(self) -> bytes:
        m = self.modes
        return m.contact.tobytes() + m.anchor.tobytes() + m.joint.tobytes() + bytes([self.t_impact is None])

    def _compute(self, t: float, y: np.ndarray) -> dict:
        p, st, ws = self.p, self.st, self.ws
        st[k.S_Q : k.S_Q + 5] = y[0:5]
        st[k.S_V : k.S_V + 5] = y[5:10]
        M, f, pts, vel, J = k.kinematics_views(ws)
        k.kinematics(p, st, M, f, pts, vel, J)
        M = M.copy()
        f = f.copy()
        V = y[5:10]
        qE = y[10:12]
        w = y[12:14]
        th = y[2]
        bz = np.array([-math.sin(th), math.cos(th)])
        if self.fl[k.F_ROTORS]:
            for r in range(2):
                f += J[4 + r].T @ (k._thrust(p, w[r]) * bz)
        for row, fx, fz in self._point_forces(t, th):
            f += J[row].T @ np.array([fx, fz])
        # contacts
        d = pts @ self.n
        dd = vel @ self.n
        s = pts @ self.tv
        sd = vel @ self.tv
        # while a point is pressed in, the ground pushes but never pulls: max(0, k d + b d')
        Nraw = self._normal(d, dd)
        N = np.maximum(0.0, Nraw)
        Ft = np.zeros(k.N_POINTS)
        mu = np.full(k.N_POINTS, p[k.P_MUK])
        if self.fl[k.F_MU_GROWTH]:  # eq. 4 per leg: its joint's speed outward along the surface
            for j, out in self._growing:
                mu[j] *= max(1.0, 1.0 + p[k.P_FMU] * out * (vel[2 + j] @ self.tv))
        if self.fl[k.F_STRIBECK]:
            weak = np.exp(-((np.abs(sd) / p[k.P_VSTR]) ** p[k.P_DSTR]))
            mu = mu + np.maximum(0.0, p[k.P_MUS] - mu) * weak
        mu = self._foot_friction(t, sd, mu)
        for i in range(k.N_POINTS):
            m = self.modes.contact[i]
            if m == 0:
                continue
            if self.fl[k.F_STICTION]:
                if m == 1:
                    Ft[i] = -p[k.P_KT] * (s[i] - self.modes.anchor[i]) - p[k.P_BT] * sd[i]
                else:
                    Ft[i] = -(1.0 if m == 2 else -1.0) * mu[i] * N[i]
            elif self.fl[k.F_REGULARISED]:
                Ft[i] = -mu[i] * N[i] * math.tanh(sd[i] / p[k.P_VS])
            f += J[i].T @ (N[i] * self.n + Ft[i] * self.tv)
        # joints
        tau = self.ctx[k.C_TAU : k.C_TAU + 2].copy()
        if self.fl[k.F_TAU_GROWTH]:  # eq. 3 per leg: its foot's friction pointing inward
            for j, inward in ((j, -out) for j, out in self._growing):
                tau[j] *= 1.0 + p[k.P_FTAU] * max(0.0, inward * Ft[j])
        tau = self._joint_torque(t, V, tau)
        qEd = np.zeros(2)
        locked = np.zeros(5, dtype=bool)
        net = np.zeros(2)  # torque the friction must hold while a joint is stuck
        zone = np.zeros(2)
        for j in range(2):
            qi = 3 + j
            qc, vc, m = y[qi], V[qi], self.modes.joint[j]
            if self.rigid:
                locked[qi] = True
                continue
            if self.flex:
                z = 1.0 if qE[j] < self.q_zone else 0.0
                zone[j] = z
                if m == 0:
                    T = self.kq * (qE[j] - qc) - self.bq * vc
                    net[j] = T - z * self.ke * (self.q_zone - qE[j])
                else:
                    B = self.bq + z * self.be
                    K = self.kq + z * self.ke
                    c0 = -tau[j] * m + z * self.ke * self.q_zone + self.kq * qc + self.bq * vc
                    qEd[j] = (c0 - K * qE[j]) / B
                    T = self.kq * (qE[j] - qc) + self.bq * (qEd[j] - vc)
                f[qi] += T
            else:
                z = 1.0 if qc < self.q_zone else 0.0
                zone[j] = z
                if m == 0:
                    locked[qi] = True
                else:
                    f[qi] += -tau[j] * m + z * (self.ke * (self.q_zone - qc) - self.be * vc)
                    qEd[j] = vc
        free = ~locked
        acc = np.zeros(5)
        acc[free] = np.linalg.solve(M[np.ix_(free, free)], f[free])
        lam = M @ acc - f  # constraint forces on locked coordinates
        for j in range(2):
            if not self.flex and not self.rigid and self.modes.joint[j] == 0:
                net[j] = lam[3 + j] - zone[j] * self.ke * (self.q_zone - y[3 + j])
        wd = np.zeros(2)
        if self.fl[k.F_ROTORS]:
            wd = (self._rotor_target(t) - w) / p[k.P_TAUM]
        # Nraw, the spring-damper's own force: a rebounding foot lets go when it would pull
        return dict(acc=acc, qEd=qEd, wd=wd, d=d, dd=dd, sd=sd, N=N, Nraw=Nraw, Ft=Ft, net=net, tau=tau, s=s)

    # The seams, where a subclass adds an effect (slopelander.ident.truth); here, the model's own.
    def _point_forces(self, t: float, pitch: float) -> list[tuple[int, float, float]]:
        """Extra forces (point row, fx, fz) on the body's points."""
        return []

    def _normal(self, d: np.ndarray, dd: np.ndarray) -> np.ndarray:
        """Each point's normal force before the ground's no-pull clip."""
        return -self.kg * d - self.bg * dd

    def _foot_friction(self, t: float, sd: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """The points' sliding friction coefficients, given their slip speeds."""
        return mu

    def _joint_torque(self, t: float, V: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The two joints' slip torques, given the velocities."""
        return tau

    def _rotor_target(self, t: float) -> float:
        if self.t_impact is None or self.cond.reverse_percent == 0.0:
            return 0.0
        c = self.cond
        t_cmd = self.t_impact + c.reverse_delay
        delay = self.p[k.P_DELAY] if self.fl[k.F_REV_DELAY] else 0.0
        full = -c.reverse_percent / 100.0
        if t < t_cmd + delay:
            return 0.0
        t_end = t_cmd + c.reverse_duration  # the command ends; inf: held
        if t < t_end:
            return full
        if c.reverse_ramp <= 0.0:
            return 0.0
        return full * max(0.0, 1.0 - (t - t_end) / c.reverse_ramp)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        e = self._eval(t, y)
        return np.concatenate([y[5:10], e["acc"], e["qEd"], e["wd"]])

    # -- events --------------------------------------------------------------------------------
    def _signal(self, kind: str, i: int, sign: float = 1.0):
        """An event function: a quantity whose zero crossing is a mode change."""
        mu_s = self.p[k.P_MUS]

        def fn(t, y):
            e = self._eval(t, y)
            if kind == "slip":
                return abs(e["Ft"][i]) - mu_s * e["N"][i]
            if kind == "jslip":
                return sign * e["net"][i] - e["tau"][i]
            if kind == "jrate":
                return sign * (e["qEd"][i] if self.flex else y[8 + i])
            return sign * e[kind][i]

        return fn

    def _event_list(self, y: np.ndarray, t: float = 0.0):
        """(function, direction, action) for every mode change possible from the current modes
        and state ``y``; a joint at a stop is not offered a slip further into it."""
        out = self._all_events(y)
        if self._suppress is not None and t < self._suppress_until:
            out = [e for e in out if e[2][:2] != self._suppress]
        return out

    def _all_events(self, y: np.ndarray):
        out = []
        for i in range(k.N_POINTS):
            m = self.modes.contact[i]
            if m == 0:
                out.append((self._signal("d", i), -1, ("touch", i)))
                continue
            if self.rigid and i < 2:
                # a lightly damped skid rebounds: it leaves the ground when its force reaches zero,
                # still pressed in (as the kernel's contact does), not at zero depth
                out.append((self._signal("Nraw", i), -1, ("release", i)))
            else:
                out.append((self._signal("d", i), 1, ("release", i)))
            if self.fl[k.F_STICTION]:
                if m == 1:
                    out.append((self._signal("slip", i), 1, ("slip", i)))
                else:
                    out.append((self._signal("sd", i, 1.0 if m == 2 else -1.0), -1, ("stick", i)))
        for j in [] if self.rigid else range(2):
            m = self.modes.joint[j]
            idx = 10 + j if self.flex else 3 + j
            if m == 0:
                if y[idx] > self.q_end + 1e-12:
                    out.append((self._signal("jslip", j, 1.0), 1, ("jslip", j, -1.0)))
                if y[idx] < self.q_max - 1e-12:
                    out.append((self._signal("jslip", j, -1.0), 1, ("jslip", j, 1.0)))
            else:
                out.append((self._signal("jrate", j, m), -1, ("jstick", j)))
                inside = y[idx] < self.q_zone
                out.append((lambda t, y, idx=idx: y[idx] - self.q_zone, 1 if inside else -1, ("zone", j)))
                if m < 0:
                    out.append((lambda t, y, idx=idx: y[idx] - self.q_end, -1, ("stop", j)))
                else:
                    out.append((lambda t, y, idx=idx: y[idx] - self.q_max, 1, ("stop", j)))
        flip = self.model.criteria.flip_pitch_deg * DEG
        out.append((lambda t, y: abs(y[2]) - flip, 1, ("flip",)))
        return out

    def _apply(self, action, t, y) -> bool:
        """Change modes for an event; return True if the landing ends."""
        kind = action[0]
        if kind in _UNDO:
            self._suppress = (_UNDO[kind], action[1])
            self._suppress_until = t + 1e-7
        if kind == "touch":
            i = action[1]
            e = self._eval(t, y)
            sd = e["sd"][i]
            self.modes.contact[i] = 2 if sd > k.STICK_SPEED else (3 if sd < -k.STICK_SPEED else 1)
            self.modes.anchor[i] = e["s"][i]
            if self.t_impact is None:
                self.t_impact = t
                self.x0 = y[0:2].copy()
            if i >= 2:
                self.touched = True
        elif kind == "release":
            self.modes.contact[action[1]] = 0
        elif kind == "slip":
            i = action[1]
            self.modes.contact[i] = 2 if self._eval(t, y)["Ft"][i] < 0 else 3
        elif kind == "stick":
            i = action[1]
            self.modes.contact[i] = 1
            self.modes.anchor[i] = self._eval(t, y)["s"][i]
        elif kind == "jslip":
            self.modes.joint[action[1]] = action[2]
        elif kind == "jstick":
            self.modes.joint[action[1]] = 0
        elif kind == "stop":
            j = action[1]
            self.modes.joint[j] = 0
            idx = 10 + j if self.flex else 3 + j
            y[idx] = min(max(y[idx], self.q_end), self.q_max)
            if not self.flex:
                y[8 + j] = 0.0
        elif kind == "flip":
            return True
        return False

    # -- the run -------------------------------------------------------------------------------
    def run(self, t_end: float, sample_rate: float = 1000.0, max_events: int = 5000):
        """Integrate to ``t_end`` (s after the start); return sample times and states (raw
        kernel layout for Q, V, q_E), and whether the vehicle flipped."""
        y = np.concatenate(
            [
                self.st[k.S_Q : k.S_Q + 5],
                self.st[k.S_V : k.S_V + 5],
                self.st[k.S_QE : k.S_QE + 2],
                self.st[k.S_W : k.S_W + 2],
            ]
        )
        t = 0.0
        ts, ys = [0.0], [y.copy()]
        flipped = False
        while t < t_end - 1e-12:
            if self._make_consistent(t, y):
                flipped = True
                break
            events = self._event_list(y, t)
            funcs = []
            for fn, direction, _ in events:
                fn.terminal = True
                fn.direction = direction
                funcs.append(fn)
            # split at the rotor command times, where the right-hand side jumps
            stop = t_end
            breaks = self._time_breaks()
            if self._suppress is not None and t < self._suppress_until:
                breaks.append(self._suppress_until)
            for tb in breaks:
                if t + 1e-12 < tb < stop:
                    stop = tb
            sol = solve_ivp(
                self.rhs,
                (t, stop),
                y,
                method="Radau",
                events=funcs,
                dense_output=True,
                rtol=self.rtol,
                atol=self.atol,
                max_step=1e-3,
            )
            if sol.status < 0:
                raise RuntimeError(f"reference integration failed at t={t:.4f}: {sol.message}")
            grid = np.arange(math.ceil(t * sample_rate + 1e-9), math.floor(sol.t[-1] * sample_rate) + 1)
            for g in grid / sample_rate:
                if g > ts[-1] + 1e-12:
                    ts.append(g)
                    ys.append(sol.sol(g))
            t = float(sol.t[-1])
            y = sol.y[:, -1].copy()
            self._track(sol)
            if sol.status == 1:
                hit = [n for n, te in enumerate(sol.t_events) if len(te)]
                n = min(hit, key=lambda n: sol.t_events[n][0])
                self.events += 1
                if self._apply(events[n][2], t, y):
                    flipped = self.flipped = True
                    ts.append(t)
                    ys.append(y.copy())
                    break
                if self.events > max_events:
                    raise RuntimeError(f"more than {max_events} mode changes by t={t:.4f} s")
                # step just past the root so the same crossing is not found again at once
                y = y + 1e-12 * self.rhs(t, y)
        return np.array(ts), np.array(ys), flipped

    def _make_consistent(self, t: float, y: np.ndarray) -> bool:
        """Apply every mode change whose condition already holds (a root finder only sees
        crossings, not a start on the far side, e.g. two feet touching at once)."""
        for _ in range(20):
            for fn, direction, action in self._event_list(y, t):
                if direction == 0:
                    continue
                v = fn(t, y)
                if action[0] == "touch" and self._eval(t, y)["Nraw"][action[1]] <= 0.0:
                    continue  # pressed in but moving out faster than the spring pushes: no contact
                if (
                    (direction < 0 and v < 0.0)
                    or (direction > 0 and v > 0.0)
                    or (action[0] == "touch" and v <= 0.0)
                ):
                    self.events += 1
                    if self._apply(action, t, y):
                        return True
                    break
            else:
                return False
        return False

    def _time_breaks(self):
        if self.t_impact is None or self.cond.reverse_percent == 0.0:
            return []
        c = self.cond
        t_cmd = self.t_impact + c.reverse_delay
        delay = self.p[k.P_DELAY] if self.fl[k.F_REV_DELAY] else 0.0
        out = [t_cmd, t_cmd + delay]
        if c.thrust_ends:  # the right-hand side kinks where the ramp begins and ends
            out += [t_cmd + c.reverse_duration, t_cmd + c.reverse_duration + c.reverse_ramp]
        return out

    def _track(self, sol):
        ys = sol.y
        feet = self.modes.contact[:2] != 0
        if feet.any() and sol.t[-1] > sol.t[0]:
            n = max(2, math.ceil((sol.t[-1] - sol.t[0]) / 1e-4) + 1)
            for t in np.linspace(sol.t[0], sol.t[-1], n):
                N = self._compute(t, sol.sol(t))["N"][:2]
                self.n_peak = max(self.n_peak, float(N[feet].max()))
        self.qe_min = np.minimum(self.qe_min, ys[10:12].min(axis=1) if self.flex else ys[3:5].min(axis=1))
        self.pitch_min = min(self.pitch_min, ys[2].min())
        self.pitch_max = max(self.pitch_max, ys[2].max())

    def result(self, ts: np.ndarray, ys: np.ndarray, settled: bool) -> LandingResult:
        """Classify like the kernel, from this run's bookkeeping."""
        st = self.st.copy()
        y = ys[-1]
        st[k.S_Q : k.S_Q + 5] = y[0:5]
        st[k.S_V : k.S_V + 5] = y[5:10]
        st[k.S_QE : k.S_QE + 2] = y[10:12] if self.flex else y[3:5]
        st[k.S_QEMIN : k.S_QEMIN + 2] = self.qe_min
        st[k.S_TOUCH] = 1.0 if self.touched else 0.0
        st[k.S_NPEAK] = self.n_peak
        st[k.S_PMIN], st[k.S_PMAX] = self.pitch_min, self.pitch_max
        if self.flipped:  # the event stops exactly at the threshold; the flip is past it
            edge = self.model.criteria.flip_pitch_deg * DEG + 1e-9
            st[k.S_PMIN] = min(st[k.S_PMIN], -edge) if y[2] < 0 else st[k.S_PMIN]
            st[k.S_PMAX] = max(st[k.S_PMAX], edge) if y[2] > 0 else st[k.S_PMAX]
        st[k.S_TIMP] = self.t_impact or 0.0
        st[k.S_T] = ts[-1]
        st[k.S_X0 : k.S_X0 + 2] = self.x0
        res = np.zeros(k.N_RESULT)
        crit = self.model.criteria_array()
        slide = k._slide(self.ctx, st)
        k.classify(self.p, self.fl, self.ctx, st, crit, settled, abs(slide) > crit[k.R_SLIDE], res)
        res[k.O_SLIDE] = slide
        res[k.O_TSETTLE] = math.nan
        return LandingResult.from_row(res)


def reference_landing(cond: LandingConditions, model: Model, t_end: float, settled: bool) -> LandingResult:
    """Integrate one landing with solve_ivp to ``t_end`` and classify it.

    ``t_end`` and ``settled`` come from the kernel's run (when it found the vehicle at rest),
    so both are judged over the same time span; the comparison is of the motion itself.
    """
    ref = ReferenceLanding(model, cond)
    ts, ys, _ = ref.run(t_end)
    return ref.result(ts, ys, settled)
