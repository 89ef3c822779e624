"""Whole-process start-up of ``slopelander simulate``: does the compiled model come from the cache?

Runs ``slopelander simulate`` as separate processes (this checkout's code) and prints:

* the wall time of each run; and, in a separate process doing what ``simulate`` does, the time
  from interpreter start to the landing starting (imports done) and to its outcome (compiled
  code loaded from the cache, or compiled, and run);
* the size of numba's cache (``.nbi``/``.nbc`` files next to the model) before and after, which
  must not grow once warm;
* the same for a user effect file, run twice, then edited, then run again (a user effect runs
  on the same compiled integrator: only its own functions compile, in memory).

``--cold`` empties the caches first so that the first run compiles everything.

Usage: python benchmarks/startup.py [--runs 3] [--cold]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL_CACHE = ROOT / "src" / "slopelander" / "model" / "__pycache__"

EFFECT = textwrap.dedent(
    """
    import numba
    from slopelander.model import kernel as k
    from slopelander.model.effects import UserEffect

    @numba.njit
    def pitch_drag(t, st, ctx, up, out):
        out[2] -= up[0] * st[k.S_V + 2]{extra}

    EFFECTS = [UserEffect("pitch_drag", "air damping of pitch", pitch_drag,
                          {{"pitch_drag_coefficient": (0.05, "N*m*s/rad")}})]
    """
)


def cache_size(dirs: list[Path]) -> tuple[int, int]:
    files = [f for d in dirs if d.is_dir() for f in d.rglob("*") if f.suffix in (".nbi", ".nbc")]
    return len(files), sum(f.stat().st_size for f in files)


def run(args: list[str], env: dict[str, str]) -> tuple[float, str]:
    t0 = time.perf_counter()
    cmd = [sys.executable, "-c", "import sys; from slopelander.cli import main; sys.exit(main())", *args]
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"slopelander {' '.join(args)} failed:\n{p.stderr}")
    return wall, p.stderr.strip().splitlines()[-1] if "compiling" in p.stderr else ""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--cold", action="store_true", help="empty the caches first")
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="slopelander-startup-"))
    env = dict(os.environ)
    env["PYTHONPATH"] = f"{ROOT / 'src'}{os.pathsep}{ROOT}"
    env["SLOPELANDER_CACHE_DIR"] = str(tmp / "cache")
    dirs = [MODEL_CACHE, tmp / "cache"]
    if a.cold:
        for f in MODEL_CACHE.glob("kernel.*.nb?"):
            f.unlink()
    try:
        print(f"cache before: {cache_size(dirs)[0]} files, {cache_size(dirs)[1] / 1e6:.1f} MB")
        sim = ["simulate", "--slope", "30", "--speed", "2"]
        for i in range(a.runs):
            wall, note = run(sim, env)
            n, b = cache_size(dirs)
            print(
                f"simulate run {i + 1}: {wall:5.2f} s whole process; cache {n} files {b / 1e6:.1f} MB"
                + (" (compiled: said so on stderr)" if note else "")
            )
        probe = (
            "import time; t0 = time.perf_counter(); "
            "from slopelander.model import LandingConditions, simulate; t1 = time.perf_counter(); "
            "simulate(LandingConditions(slope_deg=30, speed=2)); t2 = time.perf_counter(); "
            "print(f'{t1 - t0:.2f} {t2 - t0:.2f}')"
        )
        p = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
        start, done = p.stdout.split()
        print(f"in a warm process: landing starts {start} s after interpreter start, outcome at {done} s")
        eff = tmp / "my_effects.py"
        eff.write_text(EFFECT.format(extra=""))
        for i in range(a.runs):
            wall, note = run([*sim, "--effects-file", str(eff)], env)
            n, b = cache_size(dirs)
            print(
                f"simulate --effects-file run {i + 1}: {wall:5.2f} s; cache {n} files {b / 1e6:.1f} MB"
                + (" (compiled)" if note else "")
            )
        eff.write_text(EFFECT.format(extra="\n    out[1] += 0.0"))
        for i in range(2):
            wall, note = run([*sim, "--effects-file", str(eff)], env)
            n, b = cache_size(dirs)
            print(
                f"edited effect file run {i + 1}: {wall:5.2f} s; cache {n} files {b / 1e6:.1f} MB"
                + (" (compiled)" if note else "")
            )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
