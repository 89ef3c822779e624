"""How often does ``diagnose`` name a missing effect when nothing is missing (and, with
``--hide``, does it find one that is)?

Control datasets: drops of the shipped model without the two downhill-leg factors (the truth),
motion-capture noise, analysed by that same model, with seven candidates (the two built-in
factors and the five user effect files of docs/examples and tests/ident/effects). Each seed
draws new drop conditions and new noise. Prints one line per seed and the count of "nothing
missing" verdicts; ``--out`` appends one JSON line per seed (so a long run can be read while it
goes, or stopped).

    python benchmarks/ident_false_discovery.py --seeds 1 20 --workers 1
    python benchmarks/ident_false_discovery.py --hide viscous_joint --seeds 1 2

With ``--hide``, the truth has that effect (at the values of the issue-22 and effects.md
proofs; the joint and foot laws on the steeper half of the spread, where they act), the
analysed model does not. Every run also records each candidate's screening share, held-out
gain and p (``--out``), from which the screening's rank correlation with the gain is read.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from ident_candidates import FILES, NAMES  # noqa: E402  (beside this script)

from slopelander.ident.diagnose import ABOVE_FLOOR, ALPHA, NOT_AMONG, diagnose  # noqa: E402
from slopelander.ident.evidence import MIN_GAIN  # noqa: E402
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize  # noqa: E402
from slopelander.model import Model, load_effects  # noqa: E402

HIDDEN = {
    "viscous_joint": ("joint_viscous_gain", 0.05, True),
    "slip_weakening": ("slip_weakening", 1.0, True),
    "hunt_crossley_ground": ("hc_damping", 0.5, False),
    "rotor_spin_down": ("spin_down_thrust", 3.0, False),
}
"""Hidden user effect -> (its parameter, the truth's value, shown on the steep half)."""


def rescore(row: dict) -> str:
    """The verdict a saved run gets under the current rule (the fits are what cost; the rule
    is read from the candidates' held-out gains and p, the residual and the floor)."""
    if any(c["p"] <= ALPHA and c["gain"] >= MIN_GAIN for c in row["candidates"]):
        return "missing"
    ratio = row["heldout"] / row["floor"]
    if ratio <= ABOVE_FLOOR:
        return "nothing missing"
    excess = (max(row["heldout"] ** 2 - row["floor"] ** 2, 0.0)) ** 0.5
    return (
        "missing, but not among these candidates"
        if excess > NOT_AMONG * row["floor"]
        else "too small to tell"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs=2, default=[1, 20], metavar=("FIRST", "LAST"))
    ap.add_argument("--drops", type=int, default=10)
    ap.add_argument("--duration", type=float, default=0.6)
    ap.add_argument("--cma-evals", type=int, default=100)
    ap.add_argument("--refit-evals", type=int, default=60)
    ap.add_argument("--ls-evals", type=int, default=5)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--builtin-only", action="store_true", help="only the two built-in candidates")
    ap.add_argument("--hide", choices=sorted(HIDDEN), help="a user effect the truth has and the model lacks")
    ap.add_argument("--out", type=Path, help="append one JSON line per seed here")
    ap.add_argument(
        "--rescore", type=Path, nargs="+", help="recount saved runs (--out files) under the current rule"
    )
    args = ap.parse_args()
    if args.rescore:
        import json as _json

        rows = [
            _json.loads(line) for f in args.rescore for line in f.read_text().splitlines() if line.strip()
        ]
        rows.sort(key=lambda r: (r.get("hidden") or "", r["seed"]))
        from scipy.stats import spearmanr

        for r in rows:
            line = f"seed {r['seed']} ({r.get('hidden') or 'control'}): {rescore(r)}"
            if r.get("hidden"):
                cs = r["candidates"]
                rho = spearmanr([c["screening"] for c in cs], [c["gain"] for c in cs]).statistic
                top = max(cs, key=lambda c: c["gain"])
                scr = sorted(cs, key=lambda c: -c["screening"])
                line += (
                    f"; screening vs held-out gain: Spearman {rho:+.2f} over {len(cs)} candidates; "
                    f"largest gain {top['name']} ({100 * top['gain']:+.0f} %) screened "
                    f"#{scr.index(top) + 1} ({100 * top['screening']:.1f} %)"
                )
            print(line)
        control = [r for r in rows if not r.get("hidden")]
        nothing = sum(rescore(r) == "nothing missing" for r in control)
        print(f"nothing missing in {nothing} of {len(control)} control seeds")
        return 0
    base = Model.default().without("downhill_torque_growth", "downhill_friction_growth")
    users = [] if args.builtin_only else [e for f in FILES for e in load_effects(f)]
    truth = base
    steep = False
    if args.hide:
        name, value, steep = HIDDEN[args.hide]
        truth = base.with_user_effect(next(e for e in users if e.name == args.hide)).with_params(
            **{name: value}
        )
    nothing = runs = found = 0
    for seed in range(args.seeds[0], args.seeds[1] + 1):
        t0 = time.perf_counter()
        conds = paper_drops(args.drops, seed=seed)
        if steep:
            conds = [c for c in paper_drops(2 * args.drops, seed=seed) if c.slope_deg >= 22.5]
        drops = synthesize(truth, conds, NoiseModel(), seed=seed, duration=args.duration)
        d = diagnose(
            base,
            drops,
            user_effects=users,
            names=NAMES,
            seed=seed,
            cma_evals=args.cma_evals,
            refit_evals=args.refit_evals,
            ls_evals=args.ls_evals,
            workers=args.workers,
        )
        verdict = d.verdict()
        runs += 1
        nothing += verdict.startswith("nothing missing")
        found += bool(args.hide and d.missing and d.missing.candidate.name == args.hide)
        best = min((r for r in d.results if r.fits), key=lambda r: r.p)
        row = {
            "seed": seed,
            "verdict": verdict.split(":")[0],
            "missing": d.missing.candidate.name if d.missing else None,
            "best_p": best.p,
            "best": best.candidate.name,
            "heldout": d.base_validation,
            "floor": d.floor,
            "seconds": round(time.perf_counter() - t0, 1),
            "hidden": args.hide,
            "values": d.missing.values() if d.missing else None,
            "candidates": [
                {
                    "name": r.candidate.name,
                    "screening": r.screening,
                    "gain": d.gain(r),
                    "p": r.p,
                    "drop_gains": np.log(d.base_heldout_mse / r.heldout_mse).round(6).tolist(),
                }
                for r in d.results
                if r.fits
            ],
        }
        print(
            f"seed {seed}: {row['verdict']} (smallest p {best.p:.3g}, {best.candidate.name}; held-out "
            f"{d.base_validation:.4f}, floor {d.floor:.4f}); {row['seconds']} s",
            flush=True,
        )
        if args.hide:
            print(d.table())
            print(verdict, flush=True)
        if args.out:
            with args.out.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
    if args.hide:
        print(f"{args.hide} named missing in {found} of {runs} seeds ({len(users) + 2} candidates)")
    else:
        print(f"nothing missing in {nothing} of {runs} control seeds ({len(users) + 2} candidates)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
