"""Identify the paper's seven parameters from 6 synthetic drops: time, error against the truth,
confidence intervals. Goal: under 2 minutes on this machine, every parameter within 2 %.

    python benchmarks/ident_speed.py [--cma-evals N] [--ls-evals N] [--restarts N] [--noise-seed S]

The truth is the shipped model; the search starts from the centre of the bounds.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]

from slopelander.ident.fit import Identifier, resolve_params  # noqa: E402
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize  # noqa: E402
from slopelander.model import Model  # noqa: E402


def run(label: str, noise: NoiseModel, seed: int, args: argparse.Namespace) -> None:
    truth = Model.default()
    drops = synthesize(truth, paper_drops(6, seed=0), noise, seed=seed)
    params = resolve_params(truth)
    t0 = time.perf_counter()
    r = (
        Identifier(
            truth,
            params,
            cma_evals=args.cma_evals,
            ls_evals=args.ls_evals,
            seed=seed,
            restarts=args.restarts,
            from_centre=True,  # from the truth, it would say nothing about the search
        )
        .fit(drops)
        .result_
    )
    dt = time.perf_counter() - t0
    print(f"\n{label}: {dt:.1f} s, {r.nfev} simulations of 6 drops, training NRMSE {r.train_nrmse:.4f}")
    print(f"{'parameter':18s} {'truth':>10s} {'fitted':>10s} {'error':>8s} {'95 % CI':>10s}  within CI")
    worst = 0.0
    for p in params:
        tv, fv = truth.params[p.name], r.values[p.name]
        err = (fv - tv) / tv
        worst = max(worst, abs(err))
        inside = abs(fv - tv) <= r.ci95[p.name]
        print(f"{p.name:18s} {tv:10.4g} {fv:10.4g} {100 * err:+7.2f}% {r.ci95[p.name]:10.2g}  {inside}")
    print(
        f"worst error {100 * worst:.2f} %; goal < 2 min and < 2 %: "
        f"{'met' if dt < 120 and worst < 0.02 else 'NOT met'}"
    )
    for w in r.warnings:
        print(f"warning: {w}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cma-evals", type=int, default=3000)
    ap.add_argument("--ls-evals", type=int, default=150)
    ap.add_argument("--restarts", type=int, default=0)
    ap.add_argument("--noise-seed", type=int, default=1)
    args = ap.parse_args()
    Model.default()  # compile (or load the cache) outside the timing
    from slopelander.model import simulate

    simulate()
    run("noiseless", NoiseModel.none(), 0, args)
    run(f"motion-capture noise (seed {args.noise_seed})", NoiseModel(), args.noise_seed, args)


if __name__ == "__main__":
    main()
