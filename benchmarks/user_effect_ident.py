"""Find a user effect hidden in synthetic drops: the setting of tests/ident/test_diagnose_user_effects.py.

Prints diagnose's ranking table and verdict for a hidden joint-torque law (docs/examples/
effect_joint_torque.py), foot-friction law (tests/ident/effects/slip_weakening.py), normal-force
law (docs/examples/effect_normal_force.py) or point force (tests/ident/effects/
rotor_spin_down.py), with the base model fitting k_g's damping and the leg's flex, and with
--fit-mu-k also mu_k. ``backlash`` and ``round_pads`` are issue 38's case: lead-screw backlash
(3.0 deg) or round foot pads (0.040 m) hidden, the candidates the docs' seven example files
(docs/examples/effect_*.py). The joint and foot laws are shown on the steeper half of the paper's
spread (8 drops), the normal force and the point force on the whole spread (10 drops).

The named candidate's intervals are diagnose's default (each value's profile; ``--intervals
sandwich`` or ``jackknife`` the other kinds); the last line says whether the printed interval
holds the hidden value.

Usage: python benchmarks/user_effect_ident.py {joint_torque,foot_friction,normal_force,point_force,
       backlash,round_pads}
       [--seed 1] [--fit-mu-k] [--intervals sandwich|jackknife|profile] [--align-ms MS] [--full-budgets]
       [--refit-from-centre]

``--full-budgets``: diagnose's own search budgets (as the command runs), not the small ones.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from slopelander.ident.clocks import align_windows
from slopelander.ident.compare import compare
from slopelander.ident.diagnose import diagnose
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize
from slopelander.model import Model, load_effects

ROOT = Path(__file__).resolve().parents[1]
FILES = {
    "viscous_joint": ROOT / "docs" / "examples" / "effect_joint_torque.py",
    "stribeck_feet": ROOT / "docs" / "examples" / "effect_foot_friction.py",
    "slip_weakening": ROOT / "tests" / "ident" / "effects" / "slip_weakening.py",
    "hunt_crossley_ground": ROOT / "docs" / "examples" / "effect_normal_force.py",
    "rotor_spin_down": ROOT / "tests" / "ident" / "effects" / "rotor_spin_down.py",
}
HIDDEN = {
    "joint_torque": ("viscous_joint", "joint_viscous_gain", 0.05),
    "foot_friction": ("slip_weakening", "slip_weakening", 1.0),
    "normal_force": ("hunt_crossley_ground", "hc_damping", 0.5),
    "point_force": ("rotor_spin_down", "spin_down_thrust", 3.0),
    "backlash": ("lead_screw_backlash", "backlash_deg", 3.0),
    "round_pads": ("round_foot_pads", "pad_radius", 0.040),
}
FROM_DOCS = ("backlash", "round_pads")
"""Hidden effects whose candidates are the docs' example files."""
WHOLE_SPREAD = ("normal_force", "point_force", "round_pads")
"""Seams that act on every drop, shown on the whole spread."""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seam", choices=sorted(HIDDEN))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--fit-mu-k", action="store_true", help="fit friction_kinetic with the base parameters")
    ap.add_argument("--intervals", choices=("sandwich", "jackknife", "profile"), default="profile")
    ap.add_argument(
        "--align-ms", type=float, default=None, help="fit each drop's clock within +- this many ms"
    )
    ap.add_argument("--full-budgets", action="store_true", help="diagnose's default search budgets")
    ap.add_argument("--refit-from-centre", action="store_true", help="diagnose's refit_from_centre")
    args = ap.parse_args()
    if args.seam in FROM_DOCS:
        files = sorted((ROOT / "docs" / "examples").glob("effect_*.py"))
        effects = {e.name: e for f in files for e in load_effects(f)}
    else:
        effects = {n: load_effects(p)[0] for n, p in FILES.items()}
    base = Model.default().without("downhill_torque_growth", "downhill_friction_growth")
    name, param, value = HIDDEN[args.seam]
    truth = base.with_user_effect(effects[name]).with_params(**{param: value})
    if args.seam in WHOLE_SPREAD:
        conds = paper_drops(10, seed=0)
    else:
        conds = [c for c in paper_drops(16, seed=0) if c.slope_deg >= 22.5]
    drops = synthesize(truth, conds, NoiseModel(), seed=args.seed, duration=0.6)
    names = ["ground_damping", "flex_stiffness", "flex_damping"]
    if args.fit_mu_k:
        names.append("friction_kinetic")
    t0 = time.perf_counter()
    d = diagnose(
        base,
        drops,
        user_effects=list(effects.values()),
        names=names,
        seed=args.seed,
        **({} if args.full_budgets else {"cma_evals": 150, "refit_evals": 100, "ls_evals": 10}),
        final_intervals=args.intervals,
        refit_from_centre=args.refit_from_centre,
        align_s=None if args.align_ms is None else args.align_ms / 1e3,
    )
    print(
        f"hidden: {name} {param} = {value}; seed {args.seed}; base fits {', '.join(names)}; "
        f"{len(drops)} drops; {time.perf_counter() - t0:.0f} s"
        + (f"; clocks aligned within +-{args.align_ms:g} ms" if args.align_ms is not None else "")
    )
    print(d.table())
    print(d.verdict())
    m = d.missing
    if m is not None and d.final is not None and param in d.final.values:
        v, half = d.final.values[param], d.final.ci95[param]
        held = "holds" if abs(v - value) <= half else "misses"
        print(f"{args.intervals}: {param} = {v:.4g} +- {half:.2g}; the hidden {value:g} {held}")
        # did the refit reach the optimum? the truth's own NRMSE on the same drops and clocks
        align = align_windows(drops, None if args.align_ms is None else args.align_ms / 1e3)
        fitted = compare(d.final.model, drops, align=align).nrmse
        own = compare(truth, drops, align=align).nrmse
        print(f"NRMSE on all drops: the refit {fitted:.4f}, the truth itself {own:.4f}")


if __name__ == "__main__":
    main()
