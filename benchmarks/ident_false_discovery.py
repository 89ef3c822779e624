"""How often does ``diagnose`` name a missing effect when nothing is missing?

Control datasets: drops of the shipped model without the two downhill-leg factors (the truth),
motion-capture noise, analysed by that same model, with seven candidates (the two built-in
factors and the five user effect files of docs/examples and tests/ident/effects). Each seed
draws new drop conditions and new noise. Prints one line per seed and the count of "nothing
missing" verdicts; ``--out`` appends one JSON line per seed (so a long run can be read while it
goes, or stopped).

    python benchmarks/ident_false_discovery.py --seeds 1 20 --workers 1
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from slopelander.ident.diagnose import diagnose  # noqa: E402
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize  # noqa: E402
from slopelander.model import Model, load_effects  # noqa: E402

FILES = [
    ROOT / "docs" / "examples" / "effect_joint_torque.py",
    ROOT / "docs" / "examples" / "effect_foot_friction.py",
    ROOT / "docs" / "examples" / "effect_normal_force.py",
    ROOT / "tests" / "ident" / "effects" / "slip_weakening.py",
    ROOT / "tests" / "ident" / "effects" / "rotor_spin_down.py",
]
NAMES = ["ground_damping", "flex_stiffness", "flex_damping"]


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
    ap.add_argument("--out", type=Path, help="append one JSON line per seed here")
    args = ap.parse_args()
    truth = Model.default().without("downhill_torque_growth", "downhill_friction_growth")
    users = [] if args.builtin_only else [e for f in FILES for e in load_effects(f)]
    nothing = runs = 0
    for seed in range(args.seeds[0], args.seeds[1] + 1):
        t0 = time.perf_counter()
        drops = synthesize(
            truth, paper_drops(args.drops, seed=seed), NoiseModel(), seed=seed, duration=args.duration
        )
        d = diagnose(
            truth,
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
        }
        print(
            f"seed {seed}: {row['verdict']} (smallest p {best.p:.3g}, {best.candidate.name}; held-out "
            f"{d.base_validation:.4f}, floor {d.floor:.4f}); {row['seconds']} s",
            flush=True,
        )
        if args.out:
            with args.out.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
    print(f"nothing missing in {nothing} of {runs} control seeds ({len(users) + 2} candidates)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
