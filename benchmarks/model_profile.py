"""Where a landing's time goes in the compiled integrator: the step's stages, the work per step.

On the drops of ``model_ratio.py`` (200: slopes 0-45 deg, 1-3 m/s, two torque levels, every
landing to the 2 s horizon), each landing's state after every step is recorded; then

* the work: steps per landing, the share in contact, steps redone as REFINE sub-steps after a
  touchdown, the active-set solves per step, contact points per step;
* the stages: each recorded state is stepped again by the first 1, 2, ... 7 stages of
  ``kernel._substep`` (kinematics, applied forces, the joints' law, the contacts with the feet's
  friction law, the implicit solve, the forces it applied, the integration); the differences of
  those times are each stage's own (ns per step, the minimum over rounds, the prefixes taking
  turns);
* the whole batch's own time per step, for comparison (the stage sum leaves out the landing's
  checks and the refined sub-steps).

Usage: python benchmarks/model_profile.py [--rounds 5] [--matched] [--effects-file FILE]
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np
from numba import njit

from slopelander import model as m
from slopelander.model import kernel as k

STAGES = (
    "kinematics",
    "applied forces",
    "joint law",
    "contacts + friction law",
    "solve (active set)",
    "contact forces",
    "integrate",
)


def prefix(n: int):
    """A compiled function that runs the first ``n`` stages on each recorded state."""

    @njit
    def run(p, fl, ctx, states, h, ws, sx, solves):  # pragma: no cover - compiled
        w = ws[0]
        k._load(w, p, fl, ctx, states[0])
        k._load_seams(w, sx)
        p, fl, ctx, st = w.p, w.fl, w.ctx, w.st
        for r in range(states.shape[0]):
            for i in range(states.shape[1]):
                st[i] = states[r, i]
            k.kinematics(p, st, w.M, w.f, w.pts, w.vel, w.J)
            if n >= 2:
                user = k._applied_forces(p, fl, ctx, st, w, sx)
            if n >= 3:
                k._joint_law(p, fl, ctx, st, h, w, sx)
            if n >= 4:
                k._contacts(p, fl, ctx, st, w, sx)
            if n >= 5:
                solves[r] = k._solve(p, fl, st, h, w, sx)
            if n >= 6:
                k._contact_forces(p, fl, ctx, st, h, w, sx, user)
            if n >= 7:
                k._integrate(p, fl, st, h, 0.0, 0.0, w)

    return run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--matched", action="store_true", help="the model as matched to the MuJoCo peer")
    ap.add_argument("--effects-file", help="add the user effects of this file")
    args = ap.parse_args()
    model = m.Model.default()
    if args.matched:
        from slopelander.peers.mujoco_drop import matched_model

        model = matched_model(model)
    if args.effects_file:
        for e in m.load_effects(args.effects_file):
            model = model.with_user_effect(e)
    g = m.condition_grid(
        slope_deg=np.linspace(0.0, 45.0, 20),
        speed=np.array([1.0, 1.5, 2.0, 2.5, 3.0]),
        tau_up=np.array([1.1, 2.3]),
    )
    g["tau_down"] = g["tau_up"]
    g["reverse_percent"] = 0.0
    p, fl, crit, h = model.params.as_array(), model.flags(), model.criteria_array(), model.dt
    _, sx = model.kernel()
    conds = g.view(np.float64).reshape(len(g), k.N_COND)
    n_max = int(model.criteria.horizon / h) + 16
    states, ctxs = [], []
    res = np.zeros(k.N_RESULT)
    for row in conds:
        rec = np.zeros((n_max, k.N_STATE))
        n = k.run_landing(p, fl, row, h, crit, False, 1, rec, sx, res)
        ctx = np.zeros(k.N_CTX)
        k.init_landing(p, fl, row, np.zeros(k.N_STATE), ctx, k.make_workspace())
        states.append(rec[:n])
        ctxs.append(ctx)
    steps = sum(len(s) - 1 for s in states)
    before = np.concatenate([s[:-1] for s in states])
    after = np.concatenate([s[1:] for s in states])
    refined = (before[:, k.S_REFINE] > 0) | (after[:, k.S_REFINE] == k.REFINE_WINDOW - 1)
    touching = (after[:, k.S_NF : k.S_NF + k.N_POINTS] > 0).sum(axis=1)
    print(
        f"load average {os.getloadavg()[0]:.1f}; {len(g)} drops to the {model.criteria.horizon:g} s horizon, "
        f"dt {h * 1e3:.4f} ms; effects: {', '.join(model.effects)}"
        + (f"; user effects: {', '.join(e.name for e in model.user_effects)}" if model.user_effects else "")
    )
    print(
        f"work: {steps / len(g):.0f} steps per landing; in contact {np.mean(touching > 0) * 100:.1f} % "
        "of steps; "
        f"redone as {k.REFINE} sub-steps {refined.mean() * 100:.2f} % of steps "
        f"(+{refined.mean() * (k.REFINE - 1) * 100:.1f} % sub-steps); points in contact per step: "
        + ", ".join(
            f"{c}: {np.mean(touching == c) * 100:.1f} %" for c in range(0, 5) if np.any(touching == c)
        )
    )

    fns = [prefix(i + 1) for i in range(len(STAGES))]
    ws = k.make_workspace()
    solves = [np.zeros(len(s), dtype=np.int64) for s in states]
    for fn in fns:  # compile outside the timing
        fn(p, fl, ctxs[0], states[0][:4], h, ws, sx, solves[0])
    numba.set_num_threads(1)
    best = np.full(len(fns), np.inf)
    for _ in range(args.rounds):
        for i, fn in enumerate(fns):
            c0 = time.process_time()
            for s, ctx, sv in zip(states, ctxs, solves, strict=True):
                fn(p, fl, ctx, s, h, ws, sx, sv)
            best[i] = min(best[i], time.process_time() - c0)
    rows = sum(len(s) for s in states)
    per = best / rows * 1e9
    own = np.diff(np.concatenate([[0.0], per]))
    print("\nstages, ns per step (a prefix's time minus the one before; minimum of rounds):")
    for name, a, b in zip(STAGES, own, per, strict=True):
        print(f"  {name:<24} {a:6.0f}   (first stages to here: {b:5.0f})")
    sv = np.concatenate(solves)
    print(
        "  active-set solves per step: "
        + ", ".join(
            f"{c}: {np.mean(sv == c) * 100:.1f} %"
            for c in range(1, k.MAX_ACTIVE_SET_ITERATIONS + 1)
            if np.any(sv == c)
        )
        + f" (mean {sv.mean():.3f})"
    )
    out = np.zeros((len(g), k.N_RESULT))
    k.run_batch(p, fl, conds[:2].copy(), h, crit, False, sx, out[:2])
    batch = np.inf
    for _ in range(max(1, args.rounds // 2)):
        c0 = time.process_time()
        k.run_batch(p, fl, conds.copy(), h, crit, False, sx, out)
        batch = min(batch, time.process_time() - c0)
    print(
        f"the batch itself: {batch / steps * 1e9:.0f} ns per step "
        f"({len(g) / batch:.0f} landings per CPU-second), the stages' sum {per[-1]:.0f}"
    )


if __name__ == "__main__":
    main()
