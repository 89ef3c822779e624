"""What the identification commands share: the analysed model's options, the search's options,
the dataset argument, the progress bar; and the model and the effects those options describe."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from slopelander.errors import SlopelanderError

if TYPE_CHECKING:
    from slopelander.model import Model


class IdentCliError(SlopelanderError):
    """A command-line setting of the identification commands that cannot be used."""


def count(least: int):
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


def add_model_options(p: argparse.ArgumentParser, what: str) -> None:
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


def add_dataset_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "dataset", type=Path, metavar="DATASET", help="folder of drop recordings (docs/recordings.md)"
    )


def add_align_option(g) -> None:
    """``--align-ms``: each drop's clock window (docs/ident.md, "Clocks")."""
    g.add_argument(
        "--align-ms",
        type=float,
        default=None,
        metavar="MS",
        help="observe the model at each drop's best clock within +-MS ms of its t = 0 (default: "
        "3x the contact's standard deviation an imported take records, else 0; 0: off)",
    )


def align_s(args: argparse.Namespace) -> float | None:
    """``--align-ms`` in seconds (None: each drop's default), refused out of 0..50 ms."""
    ms = args.align_ms
    if ms is None:
        return None
    if not 0.0 <= ms <= 50.0:  # also refuses nan
        raise IdentCliError(f"--align-ms {ms:g}: give 0..50 ms (0 observes every drop at its own t)")
    return ms / 1e3


def add_search_options(p: argparse.ArgumentParser, repeats: int, repeats_help: str) -> None:
    """The search's options; ``--repeats`` counts a different repetition in each command (its
    ``repeats_help``), hence its own default (docs/commands.md)."""
    g = p.add_argument_group("search")
    g.add_argument(
        "--fit",
        nargs="+",
        default=None,
        metavar="NAME[=LOW:HIGH]",
        help="parameters to identify, with bounds where the defaults do not suit "
        "(default: the paper's seven the model has)",
    )
    g.add_argument("--repeats", type=count(1), default=repeats, help=repeats_help)
    g.add_argument("--seed", type=int, default=0)
    g.add_argument(
        "--cma-evals", type=count(0), default=600, help="model evaluations of the global search per fit"
    )
    g.add_argument("--ls-evals", type=count(0), default=30, help="local least-squares iterations per fit")
    add_align_option(g)
    g.add_argument(
        "--optimizer",
        choices=("cma", "de"),
        default="cma",
        help="the global search: cma (CMA-ES, default) or de (scipy's differential evolution); "
        "--cma-evals is its budget either way",
    )
    g.add_argument(
        "--workers",
        type=count(1),
        default=None,
        help="processes (default: SLOPELANDER_WORKERS, else one per core)",
    )
    g.add_argument(
        "--dask",
        metavar="ADDRESS",
        help="run the evaluations on a Dask cluster, e.g. tcp://host:8786 (docs/cluster.md)",
    )
    g.add_argument("--quiet", action="store_true", help="no progress bar")


def add_intervals_option(p: argparse.ArgumentParser, what: str, default: str = "sandwich") -> None:
    """``--intervals``: how the 95 % intervals of ``what`` are made (docs/ident.md)."""
    p.add_argument(
        "--intervals",
        choices=("sandwich", "jackknife", "profile"),  # slopelander.ident.fit.INTERVALS
        default=default,
        help=f"95 %% intervals of {what}: sandwich (over drops, from central differences at the "
        "optimum; held the truth in 20 of 20 test fits), jackknife (one refit per drop left "
        "out: --ls-evals each; its refits can stay at a kink of the cost and understate) or "
        "profile (each value's profile, the others settled at each point, over drops; a scan "
        "across the bounds goes on from a lower cost the search stopped short of); "
        f"default {default}",
    )


def fit_spec(items: list[str] | None) -> tuple[list[str] | None, dict[str, tuple[float, float]]]:
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


class ProgressBar:
    """A tqdm bar counting model evaluations (silent with --quiet or without a terminal)."""

    def __init__(self, quiet: bool, desc: str) -> None:
        import sys

        from tqdm import tqdm

        self.bar = tqdm(desc=desc, unit="sim", disable=quiet or not sys.stderr.isatty())

    def __call__(self, n: int) -> None:
        self.bar.update(n)

    def close(self) -> None:
        self.bar.close()


def search_settings(args: argparse.Namespace) -> dict:
    """The search settings fit, diagnose and steps share (repeats, seed, budgets, workers, cluster)."""
    return {
        "repeats": args.repeats,
        "seed": args.seed,
        "cma_evals": args.cma_evals,
        "ls_evals": args.ls_evals,
        "align_s": align_s(args),
        "optimizer": optimizer(args),
        "workers": args.workers,
        "client": client(args),
    }


def optimizer(args: argparse.Namespace):
    """The global search named by ``--optimizer``."""
    from slopelander.ident.optimizers import optimizer_named

    return optimizer_named(args.optimizer)


def client(args: argparse.Namespace):
    """A Dask client for ``--dask`` (None without it)."""
    if not args.dask:
        return None
    if args.workers is not None:
        raise IdentCliError(
            "--workers counts processes on this machine; with --dask the cluster's worker threads "
            "do the work (start the workers with as many threads as you want used)"
        )
    from slopelander.envelope.cluster import connect

    return connect(args.dask)


def close_client(settings: dict) -> None:
    """Close the Dask client a command opened (the search settings' ``client``)."""
    if settings.get("client") is not None:
        settings["client"].close()


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


def plain(value):
    """numpy numbers in the JSON as plain ones; NaN stays NaN (json writes it as NaN)."""
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON: {type(value).__name__}")
