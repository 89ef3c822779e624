"""The first run after a fresh install: how long until the model is usable, against a baseline
commit measured in the same run.

For this checkout and for ``--against`` (a commit, default the one before the kernel's
LLVM inlining; extracted with ``git archive``), in turn: a fresh virtual environment
(``python -m venv``) with the checkout installed as a user installs it (``pip install
"<root>[sim]"``, not editable: the package and numba's in-tree cache in the venv's
site-packages, nothing compiled yet), then, in that environment, from an empty directory:

* ``slopelander simulate --slope 20`` -- the whole command, its imports and the compile of one
  landing included (wall seconds: what a user waits);
* the same again (now from numba's cache);
* the API probe: imports, the shipped model's first landing, then the first landing with a user
  effect (``docs/examples/effect_joint_torque.py``: the seam path compiles), in wall and CPU
  seconds of that process.

The install itself is not timed (the registry's speed, not the model's). ``--no-venv`` runs
the probe on ``PYTHONPATH=<root>/src`` with an empty ``NUMBA_CACHE_DIR`` instead (seconds
faster, no install). Record dated runs under ``benchmarks/results/``:

    python3 benchmarks/first_compile.py                     # this checkout vs its baseline
    python3 benchmarks/first_compile.py --against 67501ca   # vs the commit before the seams
"""

from __future__ import annotations

import argparse
import io
import os
import subprocess
import sys
import tarfile
import tempfile
import textwrap
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

PROBE = textwrap.dedent(
    """
    import sys, time
    t0, c0 = time.perf_counter(), time.process_time()
    from slopelander.model import LandingConditions, Model, load_effects, simulate
    t1, c1 = time.perf_counter(), time.process_time()
    c = LandingConditions(slope_deg=20, speed=2)
    simulate(c, full_horizon=False)
    t2, c2 = time.perf_counter(), time.process_time()
    print(f"    API: imports {t1 - t0:.1f} s ({c1 - c0:.1f} s CPU); "
          f"the shipped model's first landing {t2 - t1:.1f} s ({c2 - c1:.1f} s CPU)", flush=True)
    (e,) = load_effects(f"{sys.argv[1]}/docs/examples/effect_joint_torque.py")
    a, ac = time.perf_counter(), time.process_time()
    simulate(c, Model.default().with_user_effect(e), full_horizon=False)
    print(f"    API: + a user effect (effect_joint_torque.py): first landing "
          f"{time.perf_counter() - a:.1f} s ({time.process_time() - ac:.1f} s CPU)", flush=True)
    """
)


def load() -> str:
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def extract(commit: str, dest: Path) -> Path:
    """The checkout at ``commit`` (what an install needs: the project file, the sources, the docs'
    examples) in ``dest``."""
    tar = subprocess.run(
        ["git", "-C", str(REPO), "archive", commit, "pyproject.toml", "README.md", "src", "docs/examples"],
        check=True,
        capture_output=True,
    ).stdout
    with tarfile.open(fileobj=io.BytesIO(tar)) as tf:
        tf.extractall(dest, filter="data")
    return dest


def fresh_env(root: Path, where: Path) -> tuple[str, dict[str, str]]:
    """A new venv with ``root`` installed from source; its python and the environment to run it in."""
    subprocess.run([sys.executable, "-m", "venv", str(where)], check=True)
    py = str(where / "bin" / "python")
    t = time.perf_counter()
    r = subprocess.run(
        [py, "-m", "pip", "install", "-q", "--disable-pip-version-check", f"{root}[sim]"],
        capture_output=True,
        text=True,
    )
    if r.returncode != 0:
        raise SystemExit(f"pip install {root}[sim] failed:\n{r.stderr}")
    print(f"    installed in a fresh venv ({time.perf_counter() - t:.0f} s, not counted)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHON", "SLOPELANDER_"))}
    env["PATH"] = f"{where / 'bin'}:{env.get('PATH', '')}"
    env["PYTHONWARNINGS"] = "ignore"
    env["SLOPELANDER_CACHE_DIR"] = str(where / "slopelander-cache")
    return py, env


def measure(name: str, root: Path, tmp: Path, venv: bool) -> None:
    print(f"{name} ({root}): load average {load()} at start")
    run = tmp / "run"
    run.mkdir()
    if venv:
        py, env = fresh_env(root, tmp / "venv")
        for what in ("first", "second"):
            t = time.perf_counter()
            r = subprocess.run(
                [str(Path(py).with_name("slopelander")), "simulate", "--slope", "20"],
                env=env,
                cwd=run,
                capture_output=True,
                text=True,
            )
            if r.returncode != 0:
                raise SystemExit(f"slopelander simulate failed:\n{r.stderr}")
            print(f"    `slopelander simulate --slope 20`, {what} run: {time.perf_counter() - t:.1f} s wall")
    else:
        py = sys.executable
        env = dict(
            os.environ,
            PYTHONPATH=str(root / "src"),
            PYTHONWARNINGS="ignore",
            NUMBA_CACHE_DIR=str(tmp / "numba"),
            SLOPELANDER_CACHE_DIR=str(tmp / "effects"),
        )
    if venv:  # the probe's own empty cache: the venv's numba cache holds the first command's
        env = dict(env, NUMBA_CACHE_DIR=str(tmp / "numba-probe"))
    r = subprocess.run([py, "-c", PROBE, str(root)], env=env, cwd=run)
    if r.returncode != 0:
        raise SystemExit(f"the probe failed in {root}")
    print(f"    load average {load()} after")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", default="6bda6b7", help="baseline commit ('' to skip)")
    ap.add_argument("--no-venv", action="store_true", help="PYTHONPATH and an empty numba cache, no venv")
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores; {sys.version.split()[0]}")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        (work / "this").mkdir()
        measure("this checkout", REPO, work / "this", not args.no_venv)
        if args.against:
            (work / "base").mkdir()
            root = extract(args.against, work / "base" / "src-root")
            measure(args.against, root, work / "base", not args.no_venv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
