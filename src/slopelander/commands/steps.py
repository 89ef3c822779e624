"""``slopelander steps``: add effects one by one, re-identify, and show the error fall."""

from __future__ import annotations

import argparse
from pathlib import Path

from slopelander.commands.ident_options import (
    IdentCliError,
    ProgressBar,
    add_dataset_argument,
    add_model_options,
    add_search_options,
    build_model,
    candidate_effects,
    close_client,
    fit_spec,
    search_settings,
)
from slopelander.outputs import check_output


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "steps",
        help="add effects one by one, re-identify, and show the error fall",
        description="Base model, then + each effect in turn, re-identifying at every step: the "
        "error-fall table (training and validation NRMSE, per state) and its plot. "
        "Exit codes: 0 done, 1 an error, 2 a usage error, 130 interrupted.",
    )
    add_dataset_argument(p)
    p.add_argument(
        "--add",
        nargs="+",
        required=True,
        metavar="EFFECT",
        help="effects to add in this order (built-in names or effects of --candidates)",
    )
    p.add_argument(
        "--candidates",
        type=Path,
        nargs="+",
        metavar="FILE|FOLDER",
        help="Python files (or folders) of user effects",
    )
    p.add_argument("--plot", type=Path, metavar="PNG", help="write the error-fall plot here")
    add_model_options(p, "base")
    add_search_options(
        p,
        repeats=1,
        repeats_help="fits per step, each on its own training subset (60 %% train / 40 %% validation)",
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_output(args.plot, "--plot")
    from slopelander.ident.diagnose import BUILTIN_CANDIDATES, Candidate
    from slopelander.ident.fit import FitError
    from slopelander.ident.recording import load_dataset
    from slopelander.ident.steps import run_steps

    users = {e.name: e for e in candidate_effects(args.candidates) or []}
    effects = []
    for name in args.add:
        if name in BUILTIN_CANDIDATES:
            effects.append(Candidate(name, BUILTIN_CANDIDATES[name]))
        elif name in users:
            effects.append(Candidate(name, tuple(users[name].parameters), users[name]))
        else:
            more = ", or one of --candidates" if users else ""
            raise IdentCliError(
                f"--add {name!r}: not a candidate effect; built-in: {', '.join(BUILTIN_CANDIDATES)}{more}"
            )
    drops = load_dataset(args.dataset)
    model = build_model(args)
    for c in effects:
        if c.user is None and c.name in model.effects:
            raise IdentCliError(f"--add {c.name!r}: the base model already has it (remove it with --without)")
    names, bounds = fit_spec(args.fit)
    settings = search_settings(args)
    bar = ProgressBar(args.quiet, "steps")
    try:
        st = run_steps(
            model,
            drops,
            effects,
            names=names,
            bounds=bounds,
            **settings,
            progress=bar,
        )
    except FitError as exc:
        raise IdentCliError(str(exc)) from None
    finally:
        bar.close()
        close_client(settings)
    print(st.table())
    if args.plot:
        print(f"plot: {st.plot(args.plot)}")
    return 0
