"""How often a fit's printed 95 % interval holds the truth, over noise seeds.

Drops of a known truth are fitted again and again with new motion-capture noise (``--seeds``);
each fit's interval (``FitResult.ci95``) either holds the value the drops were made with or not.
Nominal coverage is 95 %; the count comes with its own 95 % range (Wilson), so 20 seeds can
only tell 95 % from about 75 %. Both kinds of interval are judged on the same fits: the sandwich
over drops (the default) and the leave-one-drop-out jackknife (``--intervals jackknife``).

``--truth model``: drops from the model itself (``slopelander.ident.synth``: the same
integrator, motion-capture noise), where the only error is noise. ``--truth independent``: drops
from the independent truth simulator (``slopelander.ident.truth``: solve_ivp, its own
motion-capture model), where part of the residual is model error, as in real data.

``--latency`` sets the model truth's recording lag (its t = 0 is the true contact, its frames
show the body that long before); ``--align-ms`` fits each drop's clock within that window.

Usage: python benchmarks/interval_coverage.py [--truth model|independent] [--seeds 20] [--drops 8]
       [--latency S] [--align-ms MS] [--profile]

``--profile`` also judges ``intervals="profile"`` (a second fit per seed) and prints each kind's
median half-width of k_g: a kind can hold the truth by being wide.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from slopelander.ident.fit import Identifier
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize
from slopelander.model import Model

TRUTH = {"ground_stiffness": 3.0e4, "friction_kinetic": 0.65}


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % range of a proportion k / n (Wilson's score interval)."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def tally(values: dict, truth: dict, half: dict, held: dict, kinds=None) -> list[str]:
    """Whether each kind's 95 % interval (``half[kind][name]``) around each fitted value holds the
    truth: counted into ``held[kind][name]``; one printable phrase per parameter. ``kinds``: only
    these of ``held``'s kinds (default all)."""
    line = []
    for name, value in truth.items():
        words = []
        for kind in kinds or held:
            inside = abs(values[name] - value) <= half[kind][name]
            held[kind][name] += inside
            words.append(f"{kind} +-{half[kind][name]:.2g} {'holds' if inside else 'misses'}")
        line.append(f"{name} {values[name]:.5g} ({', '.join(words)})")
    return line


def print_coverage(held: dict, n: int, what: str) -> None:
    """Each kind's count of fits whose interval held ``what`` (a phrase, e.g. "the truth"), with its
    95 % range."""
    for kind in held:
        for name, k in held[kind].items():
            lo, hi = wilson(k, n)
            print(
                f"{kind:>9} {name}: the 95 % interval held {what(name)} in {k} of {n} fits "
                f"({100 * k / n:.0f} %, 95 % range {100 * lo:.0f}-{100 * hi:.0f} %)"
            )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--truth", choices=("model", "independent"), default="model")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--drops", type=int, default=8)
    ap.add_argument("--duration", type=float, default=0.6)
    ap.add_argument("--cma-evals", type=int, default=60)
    ap.add_argument("--ls-evals", type=int, default=15)
    ap.add_argument(
        "--latency",
        type=float,
        default=NoiseModel().latency,
        help="s the model-truth recording lags the true contact (default the noise model's)",
    )
    ap.add_argument(
        "--align-ms",
        type=float,
        default=None,
        help="fit each drop's clock within +- this many ms (Identifier align_s; default: none)",
    )
    ap.add_argument("--profile", action="store_true", help="also the profile intervals (a second fit)")
    args = ap.parse_args()
    one, five, _ = os.getloadavg()
    print(
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}: interval coverage, "
        f"load {one:.1f}/{five:.1f}, truth {args.truth}"
        + (f", recording latency {args.latency * 1e3:g} ms" if args.truth == "model" else "")
        + (f", clocks aligned within +-{args.align_ms:g} ms" if args.align_ms is not None else "")
    )
    model = Model.default()
    truth = model.with_params(**TRUTH)
    conds = paper_drops(args.drops, seed=7)
    cache: dict = {}
    kinds = ("sandwich", "jackknife") + (("profile",) if args.profile else ())
    held = {k: dict.fromkeys(TRUTH, 0) for k in kinds}
    widths: dict[str, list[float]] = {k: [] for k in kinds}
    for seed in range(args.seeds):
        if args.truth == "model":
            drops = synthesize(
                truth, conds, NoiseModel(latency=args.latency), seed=seed, duration=args.duration
            )
        else:
            from slopelander.ident.truth.dataset import truth_dataset

            drops = truth_dataset(truth, conds, seed=seed, duration=args.duration, cache=cache)
        ident = Identifier(
            model,
            list(TRUTH),
            cma_evals=args.cma_evals,
            ls_evals=args.ls_evals,
            workers=1,
            seed=seed,
            align_s=None if args.align_ms is None else args.align_ms / 1e3,
        )
        r = ident.fit(drops).result_
        half = {"sandwich": r.ci95, "jackknife": ident.jackknife_ci95(drops)}
        line = tally(r.values, TRUTH, half, held, kinds[:2])
        if args.profile:  # a second fit: the profile may move on from where the search stopped
            p = ident.with_(intervals="profile").fit(drops).result_
            half["profile"] = p.ci95
            line += tally(p.values, TRUTH, {"profile": p.ci95}, held, ["profile"])
        for k in kinds:
            widths[k].append(half[k]["ground_stiffness"])
        print(f"  seed {seed:2d}: " + "; ".join(line), flush=True)
    print_coverage(held, args.seeds, lambda name: "the truth")
    for k in kinds:
        print(f"{k:>9} ground_stiffness: median half-width {np.median(widths[k]):.4g} N/m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
