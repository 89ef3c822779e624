"""Compile the model into numba's cache once, before the suite's workers start.

On a fresh checkout nothing is compiled yet, and every process that needs the model before one of
them has written it to the cache compiles it too: both workers, both workers' simulator zygotes and
the commands the tests start, at once, about 50 s of CPU each (the stepper 35 s, a landing and a
batch of landings after it; ``python3 benchmarks/first_compile.py``). Run once here, the others load
it. With the cache warm this costs the few seconds of loading it.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

_PROBE = """
from slopelander.model import LandingConditions, Model, simulate
from slopelander.model.landing import simulate_batch
from slopelander.model.stepper import Stepper

model = Model.default()
Stepper(model).step(1 / 800, 0.5, 0.5)  # the simulated vehicle's and the JSON physics' stepper
simulate(LandingConditions(slope_deg=20, speed=2), model, full_horizon=False)  # one landing
simulate_batch([LandingConditions(slope_deg=20, speed=2)] * 2, model)  # maps, tables, fits
"""


def compile_once() -> tuple[float, int]:
    """(wall seconds, exit status) of compiling, or loading, the model in a process of its own."""
    import slopelander

    # the package this run tests (pytest's pythonpath), not whichever one is installed: it is the
    # one whose cache the workers read
    src = str(Path(slopelander.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [src, os.environ.get("PYTHONPATH")]))}
    t0 = time.monotonic()
    run = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", _PROBE], capture_output=True, text=True, env=env
    )
    if run.returncode != 0:
        sys.stderr.write(run.stderr)
    return time.monotonic() - t0, run.returncode
