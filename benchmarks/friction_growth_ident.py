"""Where factor_mu (eq. 4) shows in a drop, and whether diagnose finds it hidden there.

Part 1 (always, about a second): for each slope and impact speed, how much switching eq. 4 on
at the paper's 0.57 s/m changes the landing, as an NRMSE (each state's RMS change after first
contact over its range in a 10-drop dataset of the paper's spread, angular states x2), next to
what motion-capture noise alone gives on the same drop (the noise floor), and both outcomes.

Part 2 (``--seeds``): the setting of tests/ident/test_diagnose.py's factor_mu proof, 10
survivable drops on 30-45 deg, for each noise seed: diagnose's ranking table and verdict;
``--fit-mu-k`` fits mu_k with the base parameters as well.

Usage: python benchmarks/friction_growth_ident.py [--factor 0.57] [--seeds 1 2 3] [--fit-mu-k]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from slopelander.ident.compare import WEIGHTS, compare, state_ranges
from slopelander.ident.diagnose import diagnose
from slopelander.ident.synth import NoiseModel, paper_drops, survived, synthesize, true_states
from slopelander.model import LandingConditions, Model

SLOPES = (0.0, 10.0, 20.0, 30.0, 35.0, 40.0, 45.0)
SPEEDS = (1.0, 2.0, 3.0)


def effect_table(factor: float, duration: float = 0.6) -> None:
    with_it = Model.default().without("downhill_torque_growth").with_params(factor_mu=factor)
    without = with_it.without("downhill_friction_growth")
    ranges = state_ranges(synthesize(without, paper_drops(10, seed=0), NoiseModel.none(), duration=duration))
    t = np.arange(0, round(duration * 200) + 1) / 200.0
    print(
        f"factor_mu = {factor} s/m; joint torques 1.1 N*m uphill, 1.7 N*m downhill; "
        f"{duration} s after contact"
    )
    print(
        "| slope | speed | change by eq. 4 (NRMSE) | noise floor (NRMSE) | ratio | outcome with / without |"
    )
    print("|---:|---:|---:|---:|---:|---|")
    for s in SLOPES:
        for v in SPEEDS:
            c = LandingConditions(slope_deg=s, speed=v, tau_up=1.1, tau_down=1.7)
            a, oa = true_states(with_it, c, t)
            b, ob = true_states(without, c, t)
            change = float(np.sum(WEIGHTS * np.sqrt(np.mean((a - b) ** 2, axis=0)) / ranges) / WEIGHTS.sum())
            (drop,) = synthesize(with_it, [c], NoiseModel(), seed=1, duration=duration)
            floor = compare(with_it, [drop], ranges).nrmse
            print(
                f"| {s:.0f} deg | {v:.0f} m/s | {change:.4f} | {floor:.4f} | {change / floor:.1f} "
                f"| {oa.name.lower()} / {ob.name.lower()} |"
            )


def proof(factor: float, seeds: list[int], fit_mu_k: bool) -> None:
    truth = Model.default().without("downhill_torque_growth").with_params(factor_mu=factor)
    conds = survived(truth, paper_drops(16, seed=0, slopes=(30.0, 45.0)))
    names = ["ground_damping", "flex_stiffness", "flex_damping"] + (["friction_kinetic"] if fit_mu_k else [])
    for seed in seeds:
        drops = synthesize(truth, conds, NoiseModel(), seed=seed, duration=0.6)
        t0 = time.perf_counter()
        d = diagnose(
            truth.without("downhill_friction_growth"),
            drops,
            names=names,
            seed=seed,
            cma_evals=300,
            refit_evals=300,
            refit_from_centre=True,
        )
        print(
            f"\nhidden: factor_mu = {factor}; seed {seed}; base fits {', '.join(names)}; "
            f"{len(drops)} drops; {time.perf_counter() - t0:.0f} s"
        )
        print(d.table())
        print(d.verdict())
        for r in d.results:
            if r.fits and r.candidate.name == "downhill_friction_growth":
                vals = {k: round(v, 4) for k, v in r.fits[0].values.items()}
                print(f"with eq. 4, all fitted: {vals}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--factor", type=float, default=0.57, help="hidden factor_mu, s/m (paper: 0.57)")
    ap.add_argument("--seeds", type=int, nargs="*", default=[], help="noise seeds of the diagnose runs")
    ap.add_argument("--fit-mu-k", action="store_true", help="fit friction_kinetic with the base parameters")
    args = ap.parse_args()
    effect_table(args.factor)
    if args.seeds:
        proof(args.factor, args.seeds, args.fit_mu_k)


if __name__ == "__main__":
    main()
