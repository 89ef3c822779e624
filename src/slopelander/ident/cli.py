"""``slopelander import|synth|compare|fit|diagnose|steps``: thin layers over the ident modules."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

from slopelander.errors import SlopelanderError
from slopelander.outputs import check_output, check_output_dir

if TYPE_CHECKING:
    from slopelander.model import Model


class IdentCliError(SlopelanderError):
    """A command-line setting of the identification commands that cannot be used."""


def _count(least: int):
    """An argparse type: a whole number of at least ``least``."""

    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if n < least:
            raise argparse.ArgumentTypeError(f"must be {least} or more, got {n}")
        return n

    return parse


def _model_args(p: argparse.ArgumentParser, what: str) -> None:
    g = p.add_argument_group(f"{what} model")
    g.add_argument("--params", type=Path, metavar="FILE", help="model parameter YAML (default: shipped set)")
    g.add_argument("--without", nargs="+", default=[], metavar="EFFECT", help="switch built-in effects off")
    g.add_argument("--effects-file", type=Path, metavar="FILE", help="Python file with user effects to add")
    g.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE", help="override parameters")


def _user_values(path: Path | None) -> dict[str, float]:
    """User-effect parameter values a parameter file carries (``fit --out`` writes them under
    ``user_effects``; the built-in parameter reader ignores that section)."""
    if path is None:
        return {}
    import yaml

    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError):
        return {}  # the parameter reader reports what is wrong with the file
    section = doc.get("user_effects") if isinstance(doc, dict) else None
    out = {}
    for effect, params in (section or {}).items():
        for name, entry in (params or {}).items():
            value = entry.get("value") if isinstance(entry, dict) else entry
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise IdentCliError(f"{path}: user_effects.{effect}.{name}: {value!r} is not a number")
            out[str(name)] = float(value)
    return out


def save_params(model: Model, path: Path) -> None:
    """The model's parameters as a parameter file, with its user effects' values (by effect)."""
    import yaml

    doc = model.params.to_dict()
    if model.user_effects:
        doc["user_effects"] = {
            e.name: {
                n: {"value": p.value, "unit": p.unit, "provenance": p.provenance}
                for n, p in e.parameters.items()
            }
            for e in model.user_effects
        }
    path.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True))


def build_model(args: argparse.Namespace) -> Model:
    """The model the options describe: a parameter file, effects off, user effects, overrides."""
    from slopelander.model import Model, ParameterError, load_effects

    model = Model.from_file(str(args.params)) if args.params else Model.default()
    if args.without:
        model = model.without(*args.without)
    if args.effects_file:
        for effect in load_effects(args.effects_file):
            model = model.with_user_effect(effect)
    saved = _user_values(args.params)
    if saved:
        known = model.user_parameters()
        unknown = sorted(n for n in saved if n not in known)
        if unknown:
            raise IdentCliError(
                f"--params {args.params}: values for {', '.join(unknown)}, parameters of user effects "
                "not loaded: give their file with --effects-file"
            )
        try:
            model = model.with_params(provenance="identified", **saved)
        except ParameterError as exc:
            raise IdentCliError(f"--params {args.params}: {exc}") from None
    values = {}
    for item in args.set:
        name, _, text = item.partition("=")
        try:
            values[name] = float(text)
        except ValueError:
            raise IdentCliError(f"--set {item!r}: expected NAME=NUMBER") from None
    if values:
        try:
            model = model.with_params(**values)
        except ParameterError as exc:
            raise IdentCliError(f"--set: {exc}") from None
    return model


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "synth",
        help="write a dataset of synthetic drops from a 'truth' model",
        description="Simulate drops over the paper's spread (0-45 deg, 1-3 m/s, the paper's torque "
        "levels) with a truth model and write them as recordings with motion-capture noise.",
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="dataset folder to write")
    p.add_argument("--drops", type=int, default=10, help="number of drops")
    p.add_argument("--seed", type=int, default=0, help="seed of the drop conditions and the noise")
    p.add_argument("--duration", type=float, default=1.0, help="seconds recorded after first contact")
    p.add_argument("--position-noise", type=float, default=1e-3, help="m (standard deviation)")
    p.add_argument("--angle-noise", type=float, default=0.3, help="deg (standard deviation)")
    p.add_argument("--latency", type=float, default=0.002, help="s (default 2 ms, as NoiseModel)")
    p.add_argument("--rate", type=float, default=200.0, help="sample rate, Hz")
    p.add_argument(
        "--slopes", type=float, nargs=2, default=[0.0, 45.0], metavar=("LO", "HI"), help="deg, within 0..45"
    )
    p.add_argument(
        "--speeds", type=float, nargs=2, default=[1.0, 3.0], metavar=("LO", "HI"), help="m/s, within 1..3"
    )
    p.add_argument("--no-flips", action="store_true", help="leave out the drops the truth flips on")
    _model_args(p, "truth")
    p.set_defaults(handler=run_synth)
    register_import(subparsers)
    register_compare(subparsers)
    register_fit(subparsers)
    register_diagnose(subparsers)
    register_steps(subparsers)


def run_synth(args: argparse.Namespace) -> int:
    check_output_dir(args.out, "--out")
    from slopelander.ident.recording import write_dataset
    from slopelander.ident.synth import NoiseModel, paper_drops, survived, synthesize

    if args.out.exists() and any(args.out.glob("*.csv")):
        raise IdentCliError(f"--out {args.out} already holds drops; choose an empty folder")
    if not 1 <= args.drops <= 1000:
        raise IdentCliError("--drops must lie within 1..1000")
    if not 0.05 <= args.duration <= 10:
        raise IdentCliError("--duration must lie within 0.05..10 s")
    try:
        noise = NoiseModel(args.position_noise, args.angle_noise, args.latency, args.rate)
    except ValueError as exc:
        raise IdentCliError(str(exc)) from None
    try:
        conds = paper_drops(args.drops, args.seed, slopes=tuple(args.slopes), speeds=tuple(args.speeds))
    except ValueError as exc:
        raise IdentCliError(f"--slopes/--speeds: {exc}") from None
    model = build_model(args)
    if args.no_flips:
        kept = survived(model, conds)
        if not kept:
            raise IdentCliError("--no-flips: the truth flips on every drop; choose gentler --slopes/--speeds")
        if len(kept) < len(conds):
            print(f"left out {len(conds) - len(kept)} of {len(conds)} drops: the truth flips on them")
        conds = kept
    source = "synthetic: " + (" ".join(f"without {e}" for e in args.without) or "full model")
    drops = synthesize(
        model,
        conds,
        noise,
        seed=args.seed,
        duration=args.duration,
        source=source,
    )
    write_dataset(drops, args.out)
    flips = sum(d.outcome is not None and d.outcome.name == "FLIP" for d in drops)
    print(f"wrote {len(drops)} drops ({flips} flipped) to {args.out}")
    return 0


def register_import(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "import",
        help="turn raw motion-capture takes (C3D, Vicon/Motive CSV, Qualisys TSV) into a dataset",
        description="Read each take, fit the body's marker cluster, find the roof's plane and fall line, "
        "first contact and the impact state, compute the rates (Savitzky-Golay) and the noise, and "
        "write one drop per take (docs/import.md). Nothing is written unless every take imports.",
    )
    p.add_argument("takes", type=Path, nargs="+", metavar="TAKE", help="take files, or folders of them")
    p.add_argument(
        "--markers", type=Path, required=True, metavar="YAML", help="the markers file (docs/import.md)"
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="dataset folder to create")
    p.add_argument(
        "--keep-nonplanar",
        action="store_true",
        help="put takes that are not planar enough into the dataset too (default: DIR/not-planar/)",
    )
    p.set_defaults(handler=run_import)


def run_import(args: argparse.Namespace) -> int:
    from slopelander.ident.mocap.importer import import_takes

    done = import_takes(args.takes, args.markers, args.out, keep_nonplanar=args.keep_nonplanar)
    for d in done:
        print(d.lines[0])
        print(d.lines[1])
    flagged = [d.drop.name for d in done if not d.planar]
    kept = len(done) if args.keep_nonplanar else len(done) - len(flagged)
    line = f"wrote {kept} drops to {args.out}"
    if flagged:
        where = "kept in the dataset" if args.keep_nonplanar else f"in {args.out / 'not-planar'}"
        line += f"; not planar enough ({where}): {', '.join(flagged)}"
    print(line)
    return 0


def _dataset_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "dataset", type=Path, metavar="DATASET", help="folder of drop recordings (docs/recordings.md)"
    )


def register_compare(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "compare",
        help="compare the model with recorded drops, or with the landings of a flight log",
        description="Simulate every recorded drop, report NRMSE per state, drop and phase, outcome "
        "matches and where the residual concentrates; write a Markdown report with a plot "
        "per drop. Given a flight log instead (an ArduPilot DataFlash log or a MAVLink tlog, told by "
        "its content), compare each of its landings with the model at that landing's conditions on "
        "what the log can see, and write a JSON and a plot per landing (docs/flight-logs.md).",
    )
    p.add_argument(
        "dataset",
        type=Path,
        metavar="DATASET|LOG",
        help="folder of drop recordings (docs/recordings.md), or a flight log file",
    )
    p.add_argument(
        "--report",
        type=Path,
        metavar="DIR",
        help="folder for report.md and one PNG per drop; for a log, its JSON and PNG per landing "
        "(default for a log: <log name>-compare in the current folder)",
    )
    p.add_argument(
        "--json",
        type=Path,
        metavar="FILE",
        help="also write the figures as JSON (for a log: every landing's)",
    )
    g = p.add_argument_group("flight log (docs/flight-logs.md)")
    g.add_argument("--landing", type=_count(1), metavar="N", help="only the log's N-th landing")
    g.add_argument("--slope", type=float, metavar="DEG", help="the roof's slope, instead of the log's")
    g.add_argument(
        "--tau", type=float, nargs=2, metavar=("UP", "DOWN"), help="legs' friction torques, N*m per joint"
    )
    g.add_argument(
        "--angles", type=float, nargs=2, metavar=("UP", "DOWN"), help="leg angles, deg (not in the logs)"
    )
    _model_args(p, "analysed")
    p.set_defaults(handler=run_compare)


_LOG_OPTIONS = ("landing", "slope", "tau", "angles")


def run_compare(args: argparse.Namespace) -> int:
    path = args.dataset
    if path.is_file() or (not path.exists() and path.suffix.lower() in (".bin", ".tlog")):
        return run_compare_log(args)  # a file is read as a log whatever its name; a missing log says so
    given = [f"--{n}" for n in _LOG_OPTIONS if getattr(args, n) is not None]
    if given:
        raise IdentCliError(
            f"{', '.join(given)}: only for a flight log, and {args.dataset} is a dataset folder"
        )
    check_output_dir(args.report, "--report")
    check_output(args.json, "--json")
    from slopelander.ident.compare import compare
    from slopelander.ident.recording import STATES, load_dataset
    from slopelander.ident.report import write_report

    drops = load_dataset(args.dataset)
    model = build_model(args)
    c = compare(model, drops)
    ok, known = c.outcome_matches()
    print(f"NRMSE {c.nrmse:.4f} over {len(drops)} drops (angular states x2); outcomes match {ok}/{known}")
    print("  per state: " + ", ".join(f"{s} {v:.4f}" for s, v in zip(STATES, c.per_state, strict=True)))
    share = c.phase_share()
    print(
        "  per phase: "
        + ", ".join(f"{p} {v:.4f} ({100 * share[p]:.0f} % of residual)" for p, v in c.per_phase().items())
    )
    for w in c.worst_windows(3):
        print(f"  worst: {w.drop} {w.start:.2f}-{w.end:.2f} s ({w.phase}, {w.state}): {100 * w.share:.1f} %")
    if args.report:
        out = write_report(c, args.report, model_note=f"Model: effects {', '.join(model.effects)}.")
        print(f"report: {out}")
    if args.json:
        figures = {
            "nrmse": c.nrmse,
            "drops": [d.name for d in drops],
            "outcomes_match": ok,
            "outcomes_known": known,
            "per_state": dict(zip(STATES, map(float, c.per_state), strict=True)),
            "per_phase": {p: float(v) for p, v in c.per_phase().items()},
            "phase_share": {p: float(v) for p, v in share.items()},
            "worst": [
                {"drop": w.drop, "start_s": w.start, "end_s": w.end, "phase": w.phase, "state": w.state,
                 "share": w.share}
                for w in c.worst_windows(3)
            ],
            "effects": list(model.effects),
        }  # fmt: skip
        args.json.write_text(json.dumps(figures, indent=1, default=_plain) + "\n")
        print(f"json: {args.json}")
    return 0


def run_compare_log(args: argparse.Namespace) -> int:
    """``compare LOG``: each landing of a flight log against the model (docs/flight-logs.md)."""
    from slopelander.ident.flightlog.compare import compare_log, write_results
    from slopelander.ident.flightlog.conditions import Given

    report = args.report if args.report is not None else Path(f"{args.dataset.stem}-compare")
    check_output_dir(report, "--report")
    check_output(args.json, "--json")
    for name in ("tau", "angles"):
        values = getattr(args, name)
        if values is not None and not all(map(math.isfinite, values)):
            raise IdentCliError(f"--{name} {' '.join(map(str, values))}: not numbers")
    if args.slope is not None and not math.isfinite(args.slope):
        raise IdentCliError(f"--slope {args.slope}: not a number")
    model = build_model(args)
    given = Given(
        args.slope,
        tuple(args.tau) if args.tau is not None else None,
        tuple(args.angles) if args.angles is not None else None,
    )
    results = compare_log(model, args.dataset, given, args.landing)
    for r in results:
        print("\n".join(r.lines()))
    written = write_results(results, report, args.json)
    print("report: " + ", ".join(str(p) for p in written))
    return 0


def _search_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("search")
    g.add_argument(
        "--fit",
        nargs="+",
        default=None,
        metavar="NAME[=LOW:HIGH]",
        help="parameters to identify, with bounds where the defaults do not suit "
        "(default: the paper's seven the model has)",
    )
    g.add_argument(
        "--repeats", type=int, default=3, help="training subsets (each 60 %% train / 40 %% validation)"
    )
    g.add_argument("--seed", type=int, default=0)
    g.add_argument(
        "--cma-evals", type=_count(0), default=600, help="model evaluations of the global search per fit"
    )
    g.add_argument("--ls-evals", type=_count(0), default=30, help="local least-squares iterations per fit")
    g.add_argument(
        "--optimizer",
        choices=("cma", "de"),
        default="cma",
        help="the global search: cma (CMA-ES, default) or de (scipy's differential evolution); "
        "--cma-evals is its budget either way",
    )
    g.add_argument(
        "--workers",
        type=_count(1),
        default=None,
        help="processes (default: SLOPELANDER_WORKERS, else one per core)",
    )
    g.add_argument("--dask", metavar="ADDRESS", help="run on a Dask scheduler, e.g. tcp://host:8786")
    g.add_argument("--quiet", action="store_true", help="no progress bar")


def _fit_spec(items: list[str] | None) -> tuple[list[str] | None, dict[str, tuple[float, float]]]:
    if items is None:
        return None, {}
    names, bounds = [], {}
    for item in items:
        name, _, rng = item.partition("=")
        names.append(name)
        if rng:
            lo, _, hi = rng.partition(":")
            try:
                bounds[name] = (float(lo), float(hi))
            except ValueError:
                raise IdentCliError(f"--fit {item!r}: expected NAME=LOW:HIGH") from None
    return names, bounds


class _Bar:
    """A tqdm bar counting model evaluations (silent with --quiet or without a terminal)."""

    def __init__(self, quiet: bool, desc: str) -> None:
        import sys

        from tqdm import tqdm

        self.bar = tqdm(desc=desc, unit="sim", disable=quiet or not sys.stderr.isatty())

    def __call__(self, n: int) -> None:
        self.bar.update(n)

    def close(self) -> None:
        self.bar.close()


def _search_settings(args: argparse.Namespace) -> dict:
    """The search settings fit, diagnose and steps share (repeats, seed, budgets, workers, cluster)."""
    return {
        "repeats": args.repeats,
        "seed": args.seed,
        "cma_evals": args.cma_evals,
        "ls_evals": args.ls_evals,
        "optimizer": _optimizer(args),
        "workers": args.workers,
        "client": _client(args),
    }


def _optimizer(args: argparse.Namespace):
    from slopelander.ident.optimizers import optimizer_named

    return optimizer_named(args.optimizer)


def _client(args: argparse.Namespace):
    if not args.dask:
        return None
    from slopelander.envelope.sweep import connect

    return connect(args.dask)


def register_fit(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "fit",
        help="identify model parameters from recorded drops (CMA-ES + least squares)",
        description="Identify named parameters from recorded drops as the paper did: repeated fits on "
        "training subsets, validated on the other drops; prints a Table-II-style mean +- sigma, "
        "confidence intervals and identifiability warnings.",
    )
    _dataset_arg(p)
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
    _model_args(p, "analysed")
    _search_args(p)
    p.set_defaults(handler=run_fit)


def run_fit(args: argparse.Namespace) -> int:
    check_output(args.out, "--out")
    from slopelander.ident.fit import FitError, Identifier, fit_subsets
    from slopelander.ident.recording import load_dataset

    drops = load_dataset(args.dataset)
    model = build_model(args)
    names, bounds = _fit_spec(args.fit)
    settings = _search_settings(args)
    repeats, seed = settings.pop("repeats"), settings.pop("seed")
    bar = _Bar(args.quiet, "fit")
    try:
        ident = Identifier(
            model,
            names,
            bounds,
            **settings,
            progress=bar,
            restarts=args.restarts,
            from_centre=args.start == "centre",
        )
        ident.fit_params()  # an unknown name or bounds fail here, before any drop is simulated
        sf = fit_subsets(ident, drops, repeats=repeats, seed=seed)
    except FitError as exc:
        raise IdentCliError(str(exc)) from None
    finally:
        bar.close()
    print(sf.table())
    for w in sf.warnings():
        print(f"warning: {w}")
    from slopelander.ident.compare import compare

    means = {n: m for n, (m, _) in sf.mean_sd().items()}
    fitted = model.with_params(**means)
    before, after = compare(model, drops).nrmse, compare(fitted, drops).nrmse
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


def register_diagnose(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "diagnose",
        help="find which physical effect the model is missing",
        description="Refit the model with each candidate effect it lacks (built-in: leg_flex, "
        "downhill_torque_growth, downhill_friction_growth; plus --candidates), predict each drop "
        "with fits that did not see it, and name a candidate missing only when its held-out gains "
        "pass a sign-flip test over drops (5 % level, corrected for the candidates tried); "
        "compare the residual with the recordings' noise floor. Exit codes: 0 nothing missing, "
        "3 missing and named, 4 missing but not among the candidates, 5 too small to tell (or no "
        "noise declared to tell it by), 1 an error.",
    )
    _dataset_arg(p)
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
    _model_args(p, "analysed")
    _search_args(p)
    p.set_defaults(handler=run_diagnose, repeats=1)


def candidate_effects(paths: list[Path] | None) -> list | None:
    """The user effects of the ``--candidates`` files and folders (every ``*.py`` of a folder)."""
    if not paths:
        return None
    from slopelander.model import load_effects

    files = []
    for path in paths:
        if path.is_dir():
            found = sorted(path.glob("*.py"))
            if not found:
                raise IdentCliError(f"--candidates {path}: the folder holds no Python file")
            files += found
        else:
            files.append(path)
    return [e for f in files for e in load_effects(f)]


#: ``diagnose``'s exit codes by verdict (1: an error, 2: a usage error, as every command)
DIAGNOSE_EXIT = {"nothing_missing": 0, "missing": 3, "not_among": 4, "too_small": 5, "unknown": 5}


def run_diagnose(args: argparse.Namespace) -> int:
    from slopelander.ident.diagnose import diagnose

    check_output(args.json, "--json")
    from slopelander.ident.fit import FitError
    from slopelander.ident.recording import load_dataset

    drops = load_dataset(args.dataset)
    model = build_model(args)
    names, bounds = _fit_spec(args.fit)
    users = candidate_effects(args.candidates)
    bar = _Bar(args.quiet, "diagnose")
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
            **_search_settings(args),
            progress=bar,
        )
    except FitError as exc:
        raise IdentCliError(str(exc)) from None
    finally:
        bar.close()
    print(d.table())
    print(d.verdict())
    weighing = d.weighing()
    if weighing:
        print(weighing)
    if args.json:
        args.json.write_text(json.dumps(d.to_dict(), indent=1, default=_plain) + "\n")
        print(f"json: {args.json}")
    return DIAGNOSE_EXIT[d.kind]


def _plain(value):
    """numpy numbers in the JSON as plain ones; NaN stays NaN (json writes it as NaN)."""
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON: {type(value).__name__}")


def register_steps(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "steps",
        help="add effects one by one, re-identify, and show the error fall",
        description="Base model, then + each effect in turn, re-identifying at every step: the "
        "error-fall table (training and validation NRMSE, per state) and its plot.",
    )
    _dataset_arg(p)
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
    _model_args(p, "base")
    _search_args(p)
    p.set_defaults(handler=run_steps_cmd, repeats=1)


def run_steps_cmd(args: argparse.Namespace) -> int:
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
    names, bounds = _fit_spec(args.fit)
    bar = _Bar(args.quiet, "steps")
    try:
        st = run_steps(
            model,
            drops,
            effects,
            names=names,
            bounds=bounds,
            **_search_settings(args),
            progress=bar,
        )
    except FitError as exc:
        raise IdentCliError(str(exc)) from None
    finally:
        bar.close()
    print(st.table())
    if args.plot:
        print(f"plot: {st.plot(args.plot)}")
    return 0
