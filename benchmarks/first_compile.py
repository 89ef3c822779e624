"""First-call compile time of the model, in a fresh numba cache, for any checkout of the project.

Runs, in a separate process with an empty ``NUMBA_CACHE_DIR`` (and an empty
``SLOPELANDER_CACHE_DIR``, where versions before 2026-11-26 wrote their generated kernels): a
20 deg landing of the shipped model, then the same with ``docs/examples/effect_joint_torque.py``,
then with ``effect_foot_friction.py``, and prints the seconds each first call took (wall and
this process's CPU: under load the wall clock stretches, the CPU much less), with the load.
It uses the public API only, so it measures an older checkout as well as this one:

    python benchmarks/first_compile.py                       # this checkout
    git archive b77d5bf src docs/examples | tar -x -C /tmp/old
    python benchmarks/first_compile.py --root /tmp/old        # the commit before the seams
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

PROBE = textwrap.dedent(
    """
    import os, sys, time
    t0, c0 = time.perf_counter(), time.process_time()
    from slopelander.model import LandingConditions, Model, load_effects, simulate
    t1, c1 = time.perf_counter(), time.process_time()
    c = LandingConditions(slope_deg=20, speed=2)
    simulate(c, full_horizon=False)
    t2, c2 = time.perf_counter(), time.process_time()
    print(f"imports {t1 - t0:.1f} s ({c1 - c0:.1f} s CPU); "
          f"the shipped model's first landing {t2 - t1:.1f} s ({c2 - c1:.1f} s CPU)", flush=True)
    for name in ("joint_torque", "foot_friction"):
        (e,) = load_effects(f"{sys.argv[1]}/docs/examples/effect_{name}.py")
        a, ac = time.perf_counter(), time.process_time()
        simulate(c, Model.default().with_user_effect(e), full_horizon=False)
        print(f"  + effect_{name}: first landing {time.perf_counter() - a:.1f} s "
              f"({time.process_time() - ac:.1f} s CPU)", flush=True)
    """
)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = Path(__file__).resolve().parents[1]
    ap.add_argument("--root", type=Path, default=here, help="checkout to measure")
    args = ap.parse_args()
    root = args.root.resolve()
    print(f"{root}: load average {'/'.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(
            os.environ,
            PYTHONPATH=str(root / "src"),
            PYTHONWARNINGS="ignore",
            NUMBA_CACHE_DIR=f"{tmp}/numba",
            SLOPELANDER_CACHE_DIR=f"{tmp}/effects",
        )
        r = subprocess.run([sys.executable, "-c", PROBE, str(root)], env=env, cwd=tmp)
    print(f"load average {'/'.join(f'{x:.1f}' for x in os.getloadavg())} after")
    return r.returncode


if __name__ == "__main__":
    sys.exit(main())
