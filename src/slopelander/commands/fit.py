"""``slopelander fit``: identify model parameters from recorded drops (CMA-ES + least squares)."""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

from slopelander.commands.ident_options import (
    IdentCliError,
    ProgressBar,
    add_dataset_argument,
    add_intervals_option,
    add_model_options,
    add_search_options,
    build_model,
    close_client,
    fit_spec,
    save_params,
    search_settings,
)
from slopelander.outputs import check_output


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "fit",
        help="identify model parameters from recorded drops (CMA-ES + least squares)",
        description="Identify named parameters from recorded drops as the paper did: repeated fits on "
        "training subsets, validated on the other drops; prints a Table-II-style mean +- sigma, "
        "confidence intervals and identifiability warnings. "
        "Exit codes: 0 done, 1 an error, 2 a usage error, 130 interrupted.",
    )
    add_dataset_argument(p)
    p.add_argument("--out", type=Path, metavar="FILE", help="write the identified parameter set (YAML)")
    p.add_argument(
        "--restarts",
        type=int,
        default=0,
        help="extra CMA-ES runs from random points, sharing the budget (noisy data)",
    )
    p.add_argument(
        "--start",
        choices=("model", "centre"),
        default="model",
        help="where the search begins: the analysed model's values (default) or the centre of the bounds",
    )
    add_intervals_option(p, "each fit")
    add_model_options(p, "analysed")
    add_search_options(
        p,
        repeats=3,
        repeats_help="fits, each on its own training subset (60 %% train / 40 %% validation): "
        "their spread is the printed sigma, so 2 or more",
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_output(args.out, "--out")
    from slopelander.ident.fit import FitError, Identifier, fit_subsets
    from slopelander.ident.recording import load_dataset

    drops = load_dataset(args.dataset)
    model = build_model(args)
    names, bounds = fit_spec(args.fit)
    settings = search_settings(args)
    repeats, seed = settings.pop("repeats"), settings.pop("seed")
    bar = ProgressBar(args.quiet, "fit")
    try:
        ident = Identifier(
            model,
            names,
            bounds,
            **settings,
            progress=bar,
            restarts=args.restarts,
            from_centre=args.start == "centre",
            intervals=args.intervals,
        )
        ident.fit_params()  # an unknown name or bounds fail here, before any drop is simulated
        sf = fit_subsets(ident, drops, repeats=repeats, seed=seed)
    except FitError as exc:
        raise IdentCliError(str(exc)) from None
    finally:
        bar.close()
        close_client(settings)
    print(sf.table())
    for w in sf.warnings():
        print(f"warning: {w}")
    lags = [1e3 * lag for f in sf.fits for lag in f.lags.values()]
    if lags:  # docs/ident.md, "Clocks"
        print(
            f"clocks: each drop observed at its best lag within its window, {min(lags):+.2f} to "
            f"{max(lags):+.2f} ms (median {statistics.median(lags):+.2f}) over the fits"
        )
    from slopelander.ident.clocks import align_windows
    from slopelander.ident.compare import compare

    means = {n: m for n, (m, _) in sf.mean_sd().items()}
    fitted = model.with_params(**means)
    clocks = align_windows(drops, ident.align_s)
    before, after = compare(model, drops, align=clocks).nrmse, compare(fitted, drops, align=clocks).nrmse
    print(
        f"on all {len(drops)} drops: NRMSE {before:.4f} with the given model, "
        f"{after:.4f} with the fitted means"
    )
    if after > before:
        print(
            "warning: the fitted means are worse than the given model on these drops "
            f"({before:.4f} -> {after:.4f}): the fits disagree (see sigma) or the search was too short"
        )
    if args.out:
        save_params(fitted, args.out)
        print(f"identified parameters: {args.out}")
    return 0
