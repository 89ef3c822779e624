"""``slopelander diagnose``: which physical effect the model is missing; its exit code is the verdict."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from slopelander.commands.ident_options import (
    IdentCliError,
    ProgressBar,
    add_dataset_argument,
    add_intervals_option,
    add_model_options,
    add_search_options,
    build_model,
    candidate_effects,
    close_client,
    fit_spec,
    plain,
    search_settings,
)
from slopelander.outputs import check_output


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "diagnose",
        help="find which physical effect the model is missing",
        description="Refit the model with each candidate effect it lacks (built-in: leg_flex, "
        "downhill_torque_growth, downhill_friction_growth; plus --candidates), predict each drop "
        "with fits that did not see it, and name a candidate missing only when its held-out gains "
        "pass a sign-flip test over drops (5 % level, corrected for the candidates tried) and it "
        "explains more than the base physics' own shape freed (joint breakaway, friction width); "
        "compare the residual with the recordings' noise floor. Exit codes: 0 nothing missing, "
        "3 missing and named, 4 missing but not among the candidates, 5 too small to tell (or no "
        "noise declared to tell it by, or not told from a difference in the base physics), 1 an error.",
    )
    add_dataset_argument(p)
    p.add_argument(
        "--candidates",
        type=Path,
        nargs="+",
        metavar="FILE|FOLDER",
        help="Python files of user effects to try, or folders of them (every *.py inside)",
    )
    p.add_argument("--refits", type=int, default=None, help="refit only the N best-screened candidates")
    p.add_argument(
        "--refit-evals",
        type=int,
        default=200,
        help="model evaluations of each candidate's refit (and the control's)",
    )
    p.add_argument(
        "--folds",
        type=int,
        default=2,
        help="cross-fitting groups: each drop is predicted by fits on the others",
    )
    p.add_argument(
        "--refit-from-centre",
        action="store_true",
        help="share each refit's search between the base optimum and the centre of the bounds "
        "(when the base model bent its parameters far to mimic the missing effect)",
    )
    p.add_argument(
        "--json", type=Path, metavar="FILE", help="also write the verdict and its evidence as JSON"
    )
    add_intervals_option(p, "a named candidate's values (its refit on every drop)", "profile")
    add_model_options(p, "analysed")
    add_search_options(
        p,
        repeats=1,
        repeats_help="times the drops are split into --folds groups "
        "(each split refits every candidate --folds times)",
    )
    p.set_defaults(handler=run)


#: ``diagnose``'s exit codes by verdict (1: an error, 2: a usage error, as every command)
DIAGNOSE_EXIT = {
    "nothing_missing": 0,
    "missing": 3,
    "not_among": 4,
    "too_small": 5,
    "base_physics": 5,
    "unknown": 5,
}


def run(args: argparse.Namespace) -> int:
    from slopelander.ident.diagnose import diagnose

    check_output(args.json, "--json")
    from slopelander.ident.fit import FitError
    from slopelander.ident.recording import load_dataset

    drops = load_dataset(args.dataset)
    model = build_model(args)
    names, bounds = fit_spec(args.fit)
    users = candidate_effects(args.candidates)
    settings = search_settings(args)
    bar = ProgressBar(args.quiet, "diagnose")
    try:
        d = diagnose(
            model,
            drops,
            user_effects=users,
            names=names,
            bounds=bounds,
            refits=args.refits,
            refit_evals=args.refit_evals,
            folds=args.folds,
            refit_from_centre=args.refit_from_centre,
            final_intervals=args.intervals,
            **settings,
            progress=bar,
        )
    except FitError as exc:
        raise IdentCliError(str(exc)) from None
    finally:
        bar.close()
        close_client(settings)
    print(d.table())
    print(d.verdict())
    weighing = d.weighing()
    if weighing:
        print(weighing)
    if args.json:
        args.json.write_text(json.dumps(d.to_dict(), indent=1, default=plain) + "\n")
        print(f"json: {args.json}")
    return DIAGNOSE_EXIT[d.kind]
