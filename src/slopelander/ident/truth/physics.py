"""The truth's physics: the model's equations integrated by solve_ivp, with one hidden effect.

Why not the analysis' own simulation: a proof that generates its data with the integrator it
then fits shares that integrator's step, its contact and stick-slip logic and its errors with
the analysis (an "inverse crime": the fit can match them exactly). Here the landing is
integrated by :class:`slopelander.model.reference.ReferenceLanding` (scipy's Radau at rtol
1e-7 between mode changes, each change found as a root), which shares only the kinematics (mass
matrix, Jacobians) and the initial state with the compiled kernel, never its fixed 0.42 ms step
or its implicit contact solve. The hidden effects are written here in plain Python from their
formulas, not taken from the candidate files the analysis is given, so a mistake in a file's
law is not copied into the truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from slopelander.ident.synth import ballistic
from slopelander.model import LandingConditions, Model, Outcome
from slopelander.model import kernel as k
from slopelander.model.reference import ReferenceLanding


@dataclass(frozen=True)
class HiddenEffect:
    """An effect the truth has and the analysed model lacks. Each seam's law defaults to the
    built-in (nothing hidden there)."""

    name: str
    """The candidate that describes it (what diagnose should name)."""
    seam: str
    values: dict[str, float] = field(default_factory=dict)
    """Its parameters by the candidate's names: what the fit should recover."""

    def joint_torque(self, t: float, leg: int, rate: float, tau: float) -> float:
        """Slip torque of a joint (N*m) given the leg's angular rate (rad/s) and the built-in."""
        return tau

    def foot_friction(self, t: float, leg: int, slip_speed: float, mu: float) -> float:
        """Sliding friction coefficient of a foot given its slip speed (m/s) and the built-in."""
        return mu

    def normal_force(self, depth: float, rate: float) -> float | None:
        """Normal force (N, unclipped) at a penetration depth (m) and rate (m/s, pressing in
        positive); None: the built-in spring-damper."""
        return None

    def point_forces(self, t: float, t_touch: float | None, pitch: float) -> list[tuple[int, float, float]]:
        """(point, world fx, world fz) forces in N; points as ``layout.PT_*`` (hubs 4, 5)."""
        return []


@dataclass(frozen=True)
class ViscousJoint(HiddenEffect):
    """tau * (1 + g |leg rate|): a joint whose torque grows with its speed."""

    def joint_torque(self, t, leg, rate, tau):
        return tau * (1.0 + self.values["joint_viscous_gain"] * abs(rate))


@dataclass(frozen=True)
class SlipWeakening(HiddenEffect):
    """mu / (1 + c |v|): a foot's grip fades as it slides faster."""

    def foot_friction(self, t, leg, slip_speed, mu):
        return mu / (1.0 + self.values["slip_weakening"] * abs(slip_speed))


@dataclass(frozen=True)
class HuntCrossley(HiddenEffect):
    """k d^1.5 (1 + 1.5 alpha d'): a Hertzian ground whose damping grows with the sink."""

    def normal_force(self, depth, rate):
        return self.values["hc_stiffness"] * depth**1.5 * (1.0 + 1.5 * self.values["hc_damping"] * rate)


SPIN_DOWN_TIME = 0.15
"""s: the rotors' coast-down time constant of the hidden spin-down."""


@dataclass(frozen=True)
class RotorSpinDown(HiddenEffect):
    """T0 exp(-(t - t_touch) / 0.15 s) per rotor along the body's axis, after first contact."""

    def point_forces(self, t, t_touch, pitch):
        if t_touch is None or t < t_touch:
            return []
        f = self.values["spin_down_thrust"] * math.exp(-(t - t_touch) / SPIN_DOWN_TIME)
        return [(4 + r, -f * math.sin(pitch), f * math.cos(pitch)) for r in range(2)]


HIDDEN: dict[str, HiddenEffect] = {
    "joint_law": ViscousJoint("viscous_joint", "joint torque", {"joint_viscous_gain": 0.05}),
    "foot_friction": SlipWeakening("slip_weakening", "foot friction", {"slip_weakening": 1.0}),
    "normal_force": HuntCrossley(
        "hunt_crossley_ground", "normal force", {"hc_stiffness": 2.0e6, "hc_damping": 0.5}
    ),
    "point_force": RotorSpinDown("rotor_spin_down", "point force", {"spin_down_thrust": 3.0}),
}
"""One hidden effect per seam, at the values of the project's hidden-effect tests; each is
described by a candidate file of docs/examples or tests/ident/effects (``name``)."""


@dataclass(frozen=True)
class Departure:
    """A small, documented way the truth's base physics departs from the analysed model's.

    Real data always differs a little from any model in its base physics, so a verdict is also
    tested on truths that are not the model's equations (benchmarks/ident_truth_table.py
    ``--departures``): an effect named on such a truth with nothing hidden, or another than the
    hidden one, only absorbed the departure."""

    name: str
    description: str
    smoothing_speed: float = 0.0
    """m/s: > 0 replaces the feet's stick/slip (a tangential spring-damper until mu_s N) by
    Coulomb friction regularised as tanh(v / v_s); the velocity weakening is kept."""
    joint_static: float = 0.0
    """> 0: the joints' friction is velocity-weakening like the feet's, tau (1 + s
    exp(-(w / w_s)^2)) at the leg's rate w: a stuck joint breaks away at (1 + s) tau and slides
    at tau, where the model's joint has one torque."""
    joint_stribeck_rate: float = 1.0
    """rad/s: w_s, the leg's rate at which the excess has fallen to 1/e."""
    joint_stribeck_power: float = 2.0
    """The excess falls as exp(-(|w| / w_s)^power): 2 is the Gaussian shape of diagnose's own
    ``joint_breakaway`` alternative, 1 an exponential one outside that family."""

    def joint_torque(self, rate: float, tau: float) -> float:
        """The joint's slip torque at the leg's rate (rad/s) given the model's."""
        if self.joint_static <= 0.0:
            return tau
        w = abs(rate) / self.joint_stribeck_rate
        return tau * (1.0 + self.joint_static * math.exp(-(w**self.joint_stribeck_power)))

    def truth_model(self, model: Model) -> Model:
        """The model the truth integrates: ``model`` with the friction law swapped, if any."""
        if self.smoothing_speed <= 0.0:
            return model
        out = model.without("foot_stiction") if "foot_stiction" in model.effects else model
        return out.with_effects("regularised_friction").with_params(
            "assumed", friction_smoothing_speed=self.smoothing_speed
        )


DEPARTURES: dict[str, Departure] = {
    d.name: d
    for d in (
        Departure("exact", "the analysed model's own equations (no departure)"),
        Departure(
            "tanh_friction",
            "another friction regularisation: feet slide with mu N tanh(v / 5 mm/s) and never "
            "stick, where the model sticks them on a tangential spring until mu_s N",
            smoothing_speed=0.005,
        ),
        # at 0.3 and 1 rad/s (breaking away at 1.3 tau) it moved the control set by nothing (0.99
        # noise floors against 1.01 exact): the legs swing far faster once they slip. At 0.5 and
        # 5 rad/s it is 2.5 floors, as large as tanh_friction (benchmarks/results/2026-12-07-departures.md)
        Departure(
            "joint_stribeck",
            "another joint model: the joints' friction weakens with speed, tau (1 + 0.5 "
            "exp(-(w / 5 rad/s)^2)) (breaking away at 1.5 tau), where the model's joint has one "
            "torque",
            joint_static=0.5,
            joint_stribeck_rate=5.0,
        ),
        # the same excess with an exponential fall: a shape outside the Gaussian family of
        # diagnose's joint_breakaway alternative (benchmarks/results/2026-12-07-departures-after.md)
        Departure(
            "joint_exp_weakening",
            "another joint model: the joints' friction weakens with speed as tau (1 + 0.5 "
            "exp(-|w| / 5 rad/s)), a slower fall than joint_stribeck's",
            joint_static=0.5,
            joint_stribeck_rate=5.0,
            joint_stribeck_power=1.0,
        ),
    )
}
"""The base-physics departures the verdicts are tested on, by name (``exact``: none)."""


class TruthLanding(ReferenceLanding):
    """The reference integration with a hidden effect at its seam (``hidden=None``: none).

    The right-hand side is the reference's (model/reference.py), through the four seams where the
    kernel has them: the
    joint's slip torque (given the leg's rate), the feet's sliding friction (after the built-in
    velocity weakening), the normal force of every pressed-in point, forces at named points.
    """

    def __init__(
        self,
        model: Model,
        cond: LandingConditions,
        hidden: HiddenEffect | None = None,
        rtol: float = 1e-7,
        atol: float = 1e-9,
        departure: Departure | None = None,
    ):
        self.departure = departure or DEPARTURES["exact"]
        super().__init__(self.departure.truth_model(model), cond, rtol, atol)
        self.hidden = hidden or HiddenEffect("none", "none")

    def _normal(self, d: np.ndarray, dd: np.ndarray) -> np.ndarray:
        """Each point's normal force before clipping (the ground's or the hidden law's). A law
        of its own is applied at every point, zero depth above the ground: a switch to the
        built-in at the surface would be a jump the solver cannot step over."""
        if self.hidden.normal_force(0.0, 0.0) is None:
            return -self.kg * d - self.bg * dd
        return np.array([self.hidden.normal_force(max(-d[i], 0.0), -dd[i]) for i in range(k.N_POINTS)])

    def _point_forces(self, t: float, pitch: float) -> list[tuple[int, float, float]]:
        return self.hidden.point_forces(t, self.t_impact, pitch)

    def _foot_friction(self, t: float, sd: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """The feet's friction law (slip speed downhill-positive), on the feet in contact."""
        dsg = 1.0 if self.ctx[k.C_SIN] >= 0.0 else -1.0
        mu = mu.copy()
        for i in range(2):
            if self.modes.contact[i] != 0:
                mu[i] = max(0.0, self.hidden.foot_friction(t, i, dsg * sd[i], mu[i]))
        return mu

    def _joint_torque(self, t: float, V: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The joints' torque law, given the leg's rate (the departure's, then the hidden one's)."""
        dep = self.departure
        return np.array(
            [
                max(0.0, self.hidden.joint_torque(t, j, V[3 + j], dep.joint_torque(V[3 + j], tau[j])))
                for j in range(2)
            ]
        )


STATE_COLUMNS = (0, 1, 2, 5, 6, 7)
"""The six recorded states (x, z, pitch and their rates) in the reference's state vector."""


def truth_states(
    model: Model,
    cond: LandingConditions,
    t: np.ndarray,
    hidden: HiddenEffect | None = None,
    *,
    resolution: float = 4000.0,
    rtol: float = 1e-7,
    departure: Departure | None = None,
) -> tuple[np.ndarray, Outcome | None]:
    """The truth's six states at times ``t`` (s from first contact; flight before it), and
    ``Outcome.FLIP`` if it flipped, else None: the other outcomes are judged at rest, which a
    0.6 s recording does not reach, and the recording format lets a drop leave its outcome
    unsaid (the kernel's, over its 2 s horizon, would not be the truth's). The integration is
    sampled at ``resolution`` Hz and interpolated linearly (at 4 kHz that moves a position by
    under 1e-6 m: far below any motion capture's noise). After a flip the last state is held.
    ``departure``: the base physics departs from ``model``'s that way (:data:`DEPARTURES`)."""
    if model.user_effects:
        raise ValueError("the truth's hidden effect is its own; give a model without user effects")
    span = float(t[-1]) + 0.01
    m = replace(model, criteria=replace(model.criteria, horizon=max(span, 0.05)))
    ref = TruthLanding(m, cond, hidden, rtol=rtol, atol=rtol * 1e-2, departure=departure)
    ts, ys, flipped = ref.run(span, sample_rate=resolution)
    t0 = ref.t_impact or 0.0  # the run starts at first contact; kept in case it does not
    tt = np.clip(t + t0, 0.0, None)
    out = np.column_stack([np.interp(tt, ts, ys[:, c]) for c in STATE_COLUMNS])
    pre = t < 0
    if pre.any():
        out[pre] = ballistic(cond, t[pre], float(ys[0, 1]), model.params["gravity"])
    return out, (Outcome.FLIP if flipped else None)
