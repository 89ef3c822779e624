"""How long ``slopelander diagnose`` takes with 7 candidate effects on 12 drops, and what compiling costs.

Prints, with the load average before and after each part:

* the integrator's first-call compile time in a fresh numba cache (one compiled integrator
  serves every model: the shipped one, a user's, every candidate), and its load time from the
  warm cache;
* each candidate's own compile: its seam law, typed and handed to the integrator (seconds, not
  a whole integrator);
* the wall time of ``slopelander diagnose DATASET --candidates ... --cma-evals 300 --workers 2``
  on 12 synthetic drops, for this checkout and for a baseline commit (``--baseline``, default
  215e09e, the code before this branch's speed work and the model's speed steps; extracted with
  ``git archive`` into a temporary folder, its numba cache warmed first), alternating round by
  round on the same drops under the same load, each a separate process with a warm cache; and
  each run's CPU time with its workers' (on a shared machine the wall time is mostly waiting:
  CPU time divided by the cores is the wall time the same run needs on an idle machine). The
  ratios baseline / this checkout are the figure; the verdict lines must agree.

Candidates: the five documented example effects (docs/examples) and two of the test suite's
(tests/ident/effects: ground_power, slip_weakening). The drops: the shipped model, 12 paper-like
conditions, motion-capture noise (``slopelander synth``).

Usage: python benchmarks/diagnose_speed.py [--compile] [--rounds 1] [--baseline 215e09e] [--cma-evals 300]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ("joint_torque", "foot_friction", "normal_force", "point_force", "torque_growth")
CANDIDATES = [
    *(ROOT / "docs" / "examples" / f"effect_{n}.py" for n in EXAMPLES),
    ROOT / "tests" / "ident" / "effects" / "ground_power.py",
    ROOT / "tests" / "ident" / "effects" / "slip_weakening.py",
]

COMPILE_PROBE = textwrap.dedent(
    """
    import sys, time
    t0 = time.perf_counter()
    from slopelander.model import LandingConditions, Model, load_effects, simulate
    from slopelander.model.seams import seam_table
    c = LandingConditions(slope_deg=20.0, speed=2.0)
    t1 = time.perf_counter()
    simulate(c, full_horizon=False)
    t2 = time.perf_counter()
    print(f"integrator: imports {t1 - t0:.1f} s, first landing (compile or cache load) {t2 - t1:.1f} s")
    for path in sys.argv[1:]:
        for e in load_effects(path):
            a = time.perf_counter()
            seam_table([e])  # types the effect's functions for their seams, takes their addresses
            b = time.perf_counter()
            simulate(c, Model.default().with_user_effect(e), full_horizon=False)
            d = time.perf_counter()
            print(f"  candidate {e.name:24s} law compile {b - a:5.1f} s, first landing {d - b:5.1f} s")
    """
)


def _env(cache: str | None, root: Path = ROOT) -> dict[str, str]:
    env = dict(os.environ, PYTHONPATH=f"{root / 'src'}{os.pathsep}{root}", PYTHONWARNINGS="ignore")
    if cache:
        env["NUMBA_CACHE_DIR"] = cache
    return env


def _load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.1f} / {five:.1f} / {fifteen:.1f} (1 / 5 / 15 min, {os.cpu_count()} cores)"


def _children_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes and their reaped workers."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _compile_times(cache: str | None, label: str) -> None:
    print(f"\n{label} ({_load()})", flush=True)
    t0 = time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-c", COMPILE_PROBE, *map(str, CANDIDATES)],
        env=_env(cache),
        capture_output=True,
        text=True,
    )
    print(r.stdout.rstrip() or r.stderr[-2000:])
    print(f"  (process wall {time.perf_counter() - t0:.1f} s; {_load()})", flush=True)


def _extract(commit: str, into: Path) -> Path:
    """The baseline's tree at ``commit`` (``git archive``), its integrator compiled once."""
    tree = into / commit
    tree.mkdir()
    tar = subprocess.run(["git", "-C", str(ROOT), "archive", commit], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(tree)], input=tar, check=True)
    warm = "from slopelander.model import LandingConditions, simulate; simulate(LandingConditions())"
    subprocess.run([sys.executable, "-c", warm], env=_env(None, tree), check=True, capture_output=True)
    return tree


def _diagnose_cmd(data: Path, args: argparse.Namespace) -> list[str]:
    cmd = [sys.executable, "-m", "slopelander.cli", "diagnose", str(data), "--candidates"]
    return [
        *cmd,
        *map(str, CANDIDATES),
        "--cma-evals",
        str(args.cma_evals),
        "--workers",
        str(args.workers),
        "--quiet",
    ]


def _start(root: Path, data: Path, args: argparse.Namespace, out: Path) -> tuple[subprocess.Popen, float]:
    with open(out, "w") as f:
        proc = subprocess.Popen(
            _diagnose_cmd(data, args), env=_env(None, root), stdout=f, stderr=subprocess.STDOUT
        )
    return proc, time.perf_counter()


def _wait(procs: list[subprocess.Popen]) -> dict[int, tuple[float, float, int]]:
    """Each process's end time, CPU seconds (its pool's processes included: they are its reaped
    children) and exit code, as each ends."""
    done: dict[int, tuple[float, float, int]] = {}
    while len(done) < len(procs):
        for proc in procs:
            if proc.pid in done:
                continue
            pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                done[pid] = (
                    time.perf_counter(),
                    ru.ru_utime + ru.ru_stime,
                    os.waitstatus_to_exitcode(status),
                )
        time.sleep(0.2)
    return done


def _verdict(code: int, out: Path, root: Path) -> str:
    text = out.read_text()
    if code not in (0, 3, 4, 5):  # diagnose's verdict codes; 1 and 2 are errors
        raise SystemExit(f"diagnose failed in {root}:\n{text[-3000:]}")
    return next((line for line in text.splitlines() if line.split(":")[0] in VERDICTS), text[-300:])


VERDICTS = (
    "missing",
    "nothing missing",
    "missing, but not among these candidates",
    "too small to tell with these drops",
)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--compile", action="store_true", help="also time the compile in a fresh cache and the warm one"
    )
    ap.add_argument("--baseline", default="215e09e", help="the commit to measure against (default 215e09e)")
    ap.add_argument("--rounds", type=int, default=1, help="baseline/this-checkout pairs, alternating")
    ap.add_argument("--cma-evals", type=int, default=300)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--drops", type=int, default=12)
    ap.add_argument(
        "--together",
        action="store_true",
        help="run the two versions at once in each round (same load, half the time)",
    )
    args = ap.parse_args()
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}: diagnose speed, {_load()}")
    if args.compile:
        with tempfile.TemporaryDirectory() as cold:
            _compile_times(cold, "fresh numba cache: what a first run after an install compiles")
        _compile_times(None, "warm cache")
    head = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    )
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "drops"
        cli = [sys.executable, "-m", "slopelander.cli"]
        subprocess.run(
            [*cli, "synth", "--out", str(data), "--drops", str(args.drops), "--seed", "1"],
            env=_env(None),
            check=True,
            capture_output=True,
        )
        base = _extract(args.baseline, Path(tmp))
        versions = {f"baseline {args.baseline}": base, f"this checkout ({head.stdout.strip()}+)": ROOT}
        print(
            f"\nslopelander diagnose, {len(CANDIDATES)} candidate files, {args.drops} drops, "
            f"--cma-evals {args.cma_evals} --workers {args.workers}; {args.rounds} round(s), "
            f"{'both at once' if args.together else 'alternating'}"
        )
        times: dict[str, list[tuple[float, float]]] = {k: [] for k in versions}
        for r in range(args.rounds):
            order = list(versions.items()) if r % 2 == 0 else list(versions.items())[::-1]
            groups = [order] if args.together else [[v] for v in order]
            for group in groups:  # one version at a time, or both at once
                before = _load()
                outs = [Path(tmp) / f"{name.split()[0]}.out" for name, _ in group]
                runs = [
                    (*_start(root, data, args, out), out) for (_, root), out in zip(group, outs, strict=True)
                ]
                ends = _wait([proc for proc, _, _ in runs])
                for (name, root), (proc, t0, out) in zip(group, runs, strict=True):
                    end, cpu, code = ends[proc.pid]
                    verdict = _verdict(code, out, root)
                    times[name].append((end - t0, cpu))
                    print(f"  round {r + 1} {name:28s} wall {end - t0:6.0f} s  CPU {cpu:6.0f} s  ({before})")
                    print(f"      {verdict[:400]}", flush=True)
        (bn, bt), (tn, tt) = times.items()
        for what, i in (("wall", 0), ("CPU", 1)):
            ratios = [b[i] / t[i] for b, t in zip(bt, tt, strict=True)]
            print(
                f"{what}: {tn} {min(t[i] for t in tt):.0f} s (best of {len(tt)}), {bn} "
                f"{min(b[i] for b in bt):.0f} s; ratio per round {', '.join(f'{x:.2f}x' for x in ratios)}"
            )
        cores = os.cpu_count() or 1
        print(
            f"on {cores} idle cores (CPU / cores): {tn} {min(t[1] for t in tt) / cores:.0f} s, "
            f"{bn} {min(b[1] for b in bt) / cores:.0f} s"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
