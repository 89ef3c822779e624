"""How long ``slopelander diagnose`` takes with 7 candidate effects on 12 drops, and what compiling costs.

Prints, with the load average before and after each part:

* the integrator's first-call compile time in a fresh numba cache (one compiled integrator
  serves every model: the shipped one, a user's, every candidate), and its load time from the
  warm cache;
* each candidate's own compile: its seam law, typed and handed to the integrator (seconds, not
  a whole integrator);
* the wall time of ``slopelander diagnose DATASET --candidates ... --cma-evals 300 --workers 2``
  on 12 synthetic drops (this checkout's code, run as a separate process, warm cache), and its
  CPU time with its workers' (on a shared machine the wall time is mostly waiting: CPU time
  divided by the cores is the wall time the same run needs on an idle machine).

Candidates: the five documented example effects (docs/examples) and two of the test suite's
(tests/ident/effects: ground_power, slip_weakening). The drops: the shipped model, 12 paper-like
conditions, motion-capture noise (``slopelander synth``).

Usage: python benchmarks/diagnose_speed.py [--skip-cold] [--cma-evals 300] [--workers 2]
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


def _env(cache: str | None) -> dict[str, str]:
    env = dict(os.environ, PYTHONPATH=f"{ROOT / 'src'}{os.pathsep}{ROOT}", PYTHONWARNINGS="ignore")
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-cold", action="store_true", help="do not time a compile in a fresh cache")
    ap.add_argument("--cma-evals", type=int, default=300)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--drops", type=int, default=12)
    args = ap.parse_args()
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}: diagnose speed, {_load()}")
    if not args.skip_cold:
        with tempfile.TemporaryDirectory() as cold:
            _compile_times(cold, "fresh numba cache: what a first run after an install compiles")
    _compile_times(None, "warm cache")
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "drops"
        cli = [sys.executable, "-m", "slopelander.cli"]
        subprocess.run(
            [*cli, "synth", "--out", str(data), "--drops", str(args.drops), "--seed", "1"],
            env=_env(None),
            check=True,
            capture_output=True,
        )
        cmd = [
            *cli,
            "diagnose",
            str(data),
            "--candidates",
            *map(str, CANDIDATES),
            "--cma-evals",
            str(args.cma_evals),
            "--workers",
            str(args.workers),
            "--quiet",
        ]
        print(f"\nslopelander diagnose, {len(CANDIDATES)} candidate files, {args.drops} drops ({_load()})")
        t0 = time.perf_counter()
        cpu0 = _children_cpu()
        r = subprocess.run(cmd, env=_env(None), capture_output=True, text=True)
        wall = time.perf_counter() - t0
        cpu = _children_cpu() - cpu0
        print(r.stdout.rstrip())
        if r.returncode:
            print(r.stderr[-3000:])
            return 1
        print(f"\ndiagnose wall time: {wall:.0f} s ({_load()})")
        print(
            f"diagnose CPU time: {cpu:.0f} s, its workers included: at least {cpu / os.cpu_count():.0f} s "
            f"of wall time on {os.cpu_count()} idle cores"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
