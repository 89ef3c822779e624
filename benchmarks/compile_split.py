"""Would the suite's compile (tests/compile_once.py) be faster split over two processes?

On an empty numba cache, alternated ``--runs`` times, each in a fresh ``NUMBA_CACHE_DIR``: the
suite's probe in one process (the stepper, then a landing and a batch), against the stepper in
one process and the landing and batch in another, side by side on the machine's cores. On a
fresh checkout (CI's) this compile is wall time of the README's test command before any test.

    python benchmarks/compile_split.py [--runs 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from tests.compile_once import _PROBE  # noqa: E402

STEPPER = """
from slopelander.model import Model
from slopelander.model.stepper import Stepper

Stepper(Model.default()).step(1 / 800, 0.5, 0.5)
"""
LANDINGS = """
from slopelander.model import LandingConditions, Model, simulate
from slopelander.model.landing import simulate_batch

model = Model.default()
simulate(LandingConditions(slope_deg=20, speed=2), model, full_horizon=False)
simulate_batch([LandingConditions(slope_deg=20, speed=2)] * 2, model)
"""


def compile_in(scripts: list[str]) -> float:
    """Wall seconds to run ``scripts`` side by side, each in a process of its own, on an empty cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": f"{REPO / 'src'}{os.pathsep}{REPO}"}
        t0 = time.monotonic()
        procs = [
            subprocess.Popen([sys.executable, "-W", "ignore", "-c", code], env=env, stderr=subprocess.DEVNULL)
            for code in scripts
        ]
        if any(p.wait() != 0 for p in procs):
            raise SystemExit("the model did not compile")
        return time.monotonic() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2, help="compiles of each kind, alternated")
    a = ap.parse_args()
    one: list[float] = []
    two: list[float] = []
    for _ in range(a.runs):
        one.append(compile_in([_PROBE]))
        print(f"  one process: {one[-1]:.1f} s (load {os.getloadavg()[0]:.1f})", flush=True)
        two.append(compile_in([STEPPER, LANDINGS]))
        print(f"  two side by side: {two[-1]:.1f} s (load {os.getloadavg()[0]:.1f})", flush=True)
    m1, m2 = statistics.median(one), statistics.median(two)
    print(
        f"compile on an empty cache, median: one process {m1:.1f} s, "
        f"two side by side {m2:.1f} s ({m1 / m2:.2f}x)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
