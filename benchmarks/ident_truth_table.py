"""Does ``diagnose`` find hidden effects in data it did not make itself, and only those?

The truth is independent of the analysis (slopelander.ident.truth): the shipped model without
the two downhill-leg factors, integrated by scipy's solve_ivp (not the analysis' fixed-step
integrator), with one hidden effect per seam written in plain Python (a viscous joint, slip-
weakening feet, a Hunt-Crossley ground, rotors spinning down after touchdown), or none (the
control), recorded by a motion-capture model (200 Hz with a random phase to contact, 2 ms
latency, 1 mm jitter on four markers and a rigid fit, 1 % of frames lost, rates by a 7-frame
least-squares slope over the frames' real times). The analysed model is the shipped model
without the two factors; the candidates are the two factors and the five user files of
docs/examples and tests/ident/effects (the hidden effects' own descriptions among them).

The joint and foot laws act where joints slip and feet slide, so their sets are the steep half
of the paper's spread (8 drops, 22.5-45 deg); the others and the control use the whole spread
(10 drops). Each seed draws new noise (and with ``--vary-conditions`` new drop conditions; by
default the conditions are those of the project's hidden-effect tests, and the truth's
integration, the slow part, is done once per set).

    python benchmarks/ident_truth_table.py --seeds 1 20 --out truth.jsonl
    python benchmarks/ident_truth_table.py --table truth.jsonl

Per set: detection rate (the hidden effect named missing), false discoveries (a wrong effect
named missing; for the control, anything named), and the hidden parameters' error when named.
``--out`` appends one JSON line per run, so a long run can be stopped and tabulated.

Real data always differs a little from any model in its base physics. ``--departures`` runs
every set on truths whose base physics departs from the analysed model's in a small,
documented way (slopelander.ident.truth.DEPARTURES: feet on tanh-regularised friction instead
of stick/slip; joints whose friction weakens with speed, breaking away at 1.5 times their slip
torque, in the shape of diagnose's joint_breakaway alternative or another), as well as on the
exact one: an effect named there with nothing hidden, or another
than the hidden one, only absorbed the departure. Printed per departure: its size (the shipped
base model's NRMSE on the set, in noise floors), the rate of wrongly named effects with its 95 %
interval (Clopper-Pearson) and the most residual a candidate explained on a control set (in
noise floors). ``--small``: 6 drops a set (4 on the steep sets: too few for any p to reach 5 %),
CMA-ES 40, refits 30, least squares 5; ``--table`` recounts saved runs under the current decision
rule (``--no-alternatives``: the rule before diagnose weighed base-physics alternatives).

    python benchmarks/ident_truth_table.py --small --sets control point_force \
        --departures exact tanh_friction joint_stribeck --seeds 1 3 --out dep.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import numpy as np  # noqa: E402
from ident_candidates import FILES, NAMES  # noqa: E402  (beside this script)
from tqdm import tqdm  # noqa: E402

from slopelander.ident.compare import compare, state_ranges  # noqa: E402
from slopelander.ident.diagnose import ALPHA, diagnose  # noqa: E402
from slopelander.ident.evidence import MIN_GAIN, names_missing, noise_floor, sign_flip_test  # noqa: E402
from slopelander.ident.synth import paper_drops  # noqa: E402
from slopelander.ident.truth import DEPARTURES, HIDDEN, MotionCapture  # noqa: E402
from slopelander.ident.truth.dataset import truth_dataset  # noqa: E402
from slopelander.model import Model, load_effects  # noqa: E402

SETS = ["joint_law", "foot_friction", "normal_force", "point_force", "control"]
STEEP = {"joint_law", "foot_friction"}


def conditions(name: str, seed: int, drops: int = 10):
    if name in STEEP:
        return [c for c in paper_drops(2 * drops - 4, seed=seed) if c.slope_deg >= 22.5][: max(drops - 2, 5)]
    return paper_drops(drops, seed=seed)


def named(row: dict, alternatives: bool = True, **rule) -> str | None:
    """The effect a saved run names missing under the current decision rule (its candidates'
    held-out NRMSE and p, the base's, the noise floor, and the base-physics alternatives' per-drop
    gains); runs saved without them keep theirs. ``alternatives=False``: the rule before
    2026-12-07 (a candidate that passes the test is named). ``rule``: names_missing's options."""
    cands = row.get("candidates")
    if cands is None or row.get("floor") is None:
        return row["missing"]
    m = names_missing(
        {c["name"]: (c["heldout"], c["p"]) for c in cands}, row["heldout"], row["floor"], ALPHA, **rule
    )
    if m is None or not alternatives:
        return m
    if "alternatives" not in row:  # saved before the rule: the verdict it printed
        return row["missing"]
    g = np.array(next(c["log_gains"] for c in cands if c["name"] == m))
    for a in row["alternatives"]:  # as Diagnosis.base_physics
        ga = np.array(a["log_gains"])
        if a["gain"] < MIN_GAIN or sign_flip_test(g - ga, ALPHA, row["seed"]).p[0] <= ALPHA:
            continue
        t = a.get("on_top")
        more = t is not None and 1.0 - t["heldout"] / a["heldout"] >= MIN_GAIN
        if more and sign_flip_test(np.array(t["log_gains"]) - ga, ALPHA, row["seed"]).p[0] <= ALPHA:
            continue
        return None
    return m


def wrong(row: dict, **rule) -> bool:
    """A named effect that is not the hidden one (with nothing hidden: any named effect)."""
    m = named(row, **rule)
    return m is not None and m != row["hidden"]


def explained(row: dict) -> float | None:
    """The residual the best candidate removes on held-out drops, in noise floors (quadrature:
    sqrt(base^2 - candidate^2) / floor)."""
    cands = row.get("candidates")
    if not cands or not row.get("floor"):
        return None
    best = min(c["heldout"] for c in cands)
    return max(row["heldout"] ** 2 - best**2, 0.0) ** 0.5 / row["floor"]


def rate_ci(k: int, n: int) -> tuple[float, float]:
    """95 % Clopper-Pearson interval of a rate of k in n."""
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(0.95, method="exact")
    return ci.low, ci.high


def departures_table(rows: list[dict], **rule) -> str:
    """Per departure: its size in noise floors and the wrongly named rate with its interval."""
    out = [
        "| truth's base physics | size: shipped base NRMSE / floor on controls (median, max) | runs "
        "| wrongly named (rate, 95 % CI) | of which on controls | hidden effect named "
        "| best candidate's explained residual / floor, controls (max) |",
        "|---|---|---:|---|---:|---:|---:|",
    ]
    for dep in DEPARTURES:
        rs = [r for r in rows if r.get("departure", "exact") == dep]
        if not rs:
            continue
        size = sorted(  # on the control sets: the departure alone
            r["shipped_nrmse"] / r["shipped_floor"] for r in rs if r.get("shipped_floor") and not r["hidden"]
        )
        sz = f"{size[len(size) // 2]:.2f}, {size[-1]:.2f}" if size else "-"
        k = sum(wrong(r, **rule) for r in rs)
        lo, hi = rate_ci(k, len(rs))
        ctl = [r for r in rs if not r["hidden"]]
        hid = [r for r in rs if r["hidden"]]
        found = f"{sum(named(r, **rule) == r['hidden'] for r in hid)} of {len(hid)}" if hid else "-"
        ex = [e for e in (explained(r) for r in ctl) if e is not None]
        rate = f"{k} ({100 * k / len(rs):.0f} %, {100 * lo:.0f}-{100 * hi:.0f} %)"
        most = f"{max(ex):.2f}" if ex else "-"
        out.append(
            f"| {dep} | {sz} | {len(rs)} | {rate} | {sum(wrong(r, **rule) for r in ctl)} of {len(ctl)} "
            f"| {found} | {most} |"
        )
    off = [r for r in rows if r.get("departure", "exact") != "exact"]
    if off:
        k = sum(wrong(r, **rule) for r in off)
        lo, hi = rate_ci(k, len(off))
        rate = f"{k} ({100 * k / len(off):.0f} %, {100 * lo:.0f}-{100 * hi:.0f} %)"
        out.append(f"| every departure | - | {len(off)} | {rate} | - | - | - |")
    return "\n".join(out)


class DiskCache:
    """The truth's dense integrations kept in a folder (``--cache``), one ``.npz`` per drop and
    hidden effect, so that a run split over processes or stopped and resumed integrates each
    drop once. Keyed by a hash of the drop's full description (effect, values, conditions,
    duration) and of the truth's own source, so a changed truth is integrated again."""

    def __init__(self, folder: Path):
        import hashlib

        from slopelander.ident.truth import physics

        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)
        self._salt = hashlib.sha256(Path(physics.__file__).read_bytes()).hexdigest()[:12]

    def _path(self, key) -> Path:
        import hashlib

        return self.folder / (hashlib.sha256(f"{self._salt}{key!r}".encode()).hexdigest()[:24] + ".npz")

    def __contains__(self, key) -> bool:
        return self._path(key).exists()

    def __getitem__(self, key):
        import numpy as np

        from slopelander.model import Outcome

        with np.load(self._path(key)) as z:
            code = int(z["outcome"])
            return z["states"], (Outcome(code) if code >= 0 else None)

    def __setitem__(self, key, value) -> None:
        import numpy as np

        states, outcome = value
        tmp = self._path(key).with_suffix(".tmp.npz")
        np.savez(tmp, states=states, outcome=np.int64(int(outcome) if outcome is not None else -1))
        tmp.replace(self._path(key))  # whole or absent: a stopped run leaves no half file


def table(rows: list[dict], **rule) -> str:
    """The markdown table of saved runs."""
    out = [
        "| set (hidden) | seeds | named missing: the hidden effect | a wrong effect | nothing missing | "
        "other verdicts | parameter error when named (median, max) | runs with a second search "
        "(groups) | s a run (median) |",
        "|---|---:|---:|---:|---:|---:|---|---:|---:|",
    ]
    for name, dep in [(n, d) for d in DEPARTURES for n in SETS]:
        rs = [r for r in rows if r["set"] == name and r.get("departure", "exact") == dep]
        if not rs:
            continue
        hidden = r0 = rs[0]["hidden"]
        right = [r for r in rs if hidden and named(r, **rule) == hidden]
        bad = [r for r in rs if wrong(r, **rule)]
        nothing = [r for r in rs if not named(r, **rule) and r["verdict"].startswith("nothing missing")]
        other = len(rs) - len(right) - len(bad) - len(nothing)
        errs = []
        for par in (rs[0]["truth"] or {}) if right else ():
            # a run recounted under another rule than its own has no refit on every drop: no error
            e = sorted(abs(r["errors"][par]) for r in right if par in r["errors"])
            if e:
                errs.append(f"{par} {100 * e[len(e) // 2]:.1f} %, {100 * e[-1]:.1f} % ({len(e)} runs)")
        label = (f"{name} ({r0})" if r0 else "control (none)") + (f", base {dep}" if dep != "exact" else "")
        seeds = ", ".join(str(r["seed"]) for r in rs)
        # runs saved before the second search existed have no count
        again = [r["restarted"] for r in rs if "restarted" in r]
        second = f"{sum(1 for n in again if n)} ({sum(again)})" if again else "-"
        secs = sorted(r["seconds"] for r in rs)
        out.append(
            f"| {label} | {len(rs)} ({seeds}) | {len(right) if hidden else '-'} | {len(bad)} | "
            f"{len(nothing)} | {other} | {'; '.join(errs) or '-'} | {second} | {secs[len(secs) // 2]:.0f} |"
        )
    return "\n".join(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs=2, default=[1, 20], metavar=("FIRST", "LAST"))
    ap.add_argument("--sets", nargs="+", choices=SETS, default=SETS)
    ap.add_argument(
        "--departures",
        nargs="+",
        choices=list(DEPARTURES),
        default=["exact"],
        help="the truth's base physics",
    )
    ap.add_argument("--drops", type=int, default=10, help="drops a set (the steep sets: 2 fewer)")
    ap.add_argument("--small", action="store_true", help="6 drops, CMA-ES 40, refits 30, least squares 5")
    ap.add_argument("--vary-conditions", action="store_true", help="new drop conditions for every seed")
    ap.add_argument("--duration", type=float, default=0.6)
    ap.add_argument("--cma-evals", type=int, default=100)
    ap.add_argument("--refit-evals", type=int, default=60)
    ap.add_argument("--ls-evals", type=int, default=5)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, help="append one JSON line per run here")
    ap.add_argument("--cache", type=Path, help="keep the truth integrations here (reused)")
    ap.add_argument("--table", type=Path, nargs="+", help="only print the table of saved runs (--out files)")
    ap.add_argument(
        "--no-alternatives",
        action="store_true",
        help="with --table: recount under the rule before 2026-12-07 (no base-physics alternatives)",
    )
    args = ap.parse_args()
    if args.table:
        rows = [json.loads(line) for f in args.table for line in f.read_text().splitlines() if line.strip()]
        rule = {"alternatives": not args.no_alternatives}
        print(table(rows, **rule))
        print()
        print(departures_table(rows, **rule))
        return 0
    if args.small:
        args.drops, args.cma_evals, args.refit_evals, args.ls_evals = 6, 40, 30, 5
    base = Model.default().without("downhill_torque_growth", "downhill_friction_growth")
    users = [e for f in FILES for e in load_effects(f)]
    mocap = MotionCapture()
    cache = DiskCache(args.cache) if args.cache else {}
    rows = []
    runs = [
        (name, seed, dep)
        for seed in range(args.seeds[0], args.seeds[1] + 1)
        for dep in args.departures
        for name in args.sets
    ]
    for name, seed, dep in tqdm(runs, desc="diagnose runs", unit="run", file=sys.stderr):
        t0 = time.perf_counter()
        hidden = HIDDEN.get(name)
        conds = conditions(name, seed if args.vary_conditions else 0, args.drops)
        drops = truth_dataset(
            base,
            conds,
            hidden,
            mocap,
            seed=seed,
            duration=args.duration,
            cache=cache,
            departure=DEPARTURES[dep],
        )
        t_truth = time.perf_counter() - t0
        ranges = state_ranges(drops)
        shipped = compare(base, drops, ranges).nrmse  # the base at the truth's own values
        shipped_floor = noise_floor(base, drops, ranges, seed=seed)
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
        values = d.missing.values() if d.missing else {}
        truth = dict(hidden.values) if hidden else None
        row = {
            "set": name,
            "departure": dep,
            "seed": seed,
            "hidden": hidden.name if hidden else None,
            "truth": truth,
            "verdict": verdict.split(":")[0],
            "missing": d.missing.candidate.name if d.missing else None,
            "values": values,
            "errors": {p: values[p] / v - 1.0 for p, v in (truth or {}).items() if p in values},
            "heldout": d.base_validation,
            "floor": d.floor,
            "best_p": min((r.p for r in d.results if r.fits), default=None),
            "shipped_nrmse": shipped,
            "shipped_floor": shipped_floor,
            "candidates": [
                {
                    "name": r.candidate.name,
                    "heldout": r.validation_nrmse,
                    "gain": d.gain(r),
                    "p": r.p,
                    "log_gains": d.log_gains(r).tolist(),
                }
                for r in d.fitted
            ],
            # refitted only when a candidate passed the test (diagnose's base-physics rule)
            "alternatives": [
                {
                    "name": a.candidate.name,
                    "heldout": a.validation_nrmse,
                    "gain": d.gain(a),
                    "log_gains": d.log_gains(a).tolist(),
                    "values": a.values(),
                    "on_top": None
                    if (t := d.on_top.get(a.candidate.name)) is None
                    else {
                        "heldout": t.validation_nrmse,
                        "log_gains": d.log_gains(t).tolist(),
                        "values": t.values(),
                    },
                }
                for a in d.alternatives
            ],
            "passed": d.passed.candidate.name if d.passed else None,
            "restarted": sum(r.restarted for r in d.results),
            "conditions_seed": seed if args.vary_conditions else 0,
            "truth_seconds": round(t_truth, 1),
            "seconds": round(time.perf_counter() - t0, 1),
        }
        rows.append(row)
        tqdm.write(f"{name} ({dep}) seed {seed}: {verdict}  ({row['seconds']} s)", file=sys.stdout)
        if args.out:
            with args.out.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
    print(table(rows))
    print()
    print(departures_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
