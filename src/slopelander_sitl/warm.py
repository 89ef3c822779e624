"""Everything a simulator loads before its first tick, loaded once: the imports (numba,
pymavlink's dialect, lupa) and the compiled model from numba's cache.

Importing this module does it: the forkserver the test suite forks its simulators from
(:mod:`slopelander_sitl.processes`) preloads it, so each simulator starts warm. A failure here is printed and
left to each simulator, which then loads what it needs itself and says what fails.

Run as a command it also compiles the model's landing and batch entry points into numba's cache,
so that no test (and no first demo) waits for a compile; ``.ci/run`` runs it before pytest:

    python3 -m slopelander_sitl.warm
"""

from __future__ import annotations

import sys
import time
import traceback

#: the simulators' entry modules; each defines ``warm()``, what it loads before its first tick
SIMULATORS = (
    "slopelander_sitl.vehicle.__main__",
    "slopelander_sitl.legboard.__main__",
    "slopelander_sitl.json_physics.__main__",
    "slopelander_sitl.ardupilot.pod",
)


def warm_simulators() -> None:
    """Import each simulator's entry module and run its ``warm()``."""
    import importlib

    for name in SIMULATORS:
        warm = getattr(importlib.import_module(name), "warm", None)
        if warm is not None:
            warm()


def compile_model() -> None:
    """Compile (or load) the model's entry points the tests and commands call: the simulated
    vehicle's stepper, one landing, and a batch of landings (maps, tables, fits)."""
    from slopelander.model import LandingConditions, Model, simulate
    from slopelander.model.landing import simulate_batch
    from slopelander.model.stepper import Stepper

    model = Model.default()
    Stepper(model).step(1 / 800, 0.5, 0.5)
    simulate(LandingConditions(slope_deg=20, speed=2), model, full_horizon=False)
    simulate_batch([LandingConditions(slope_deg=20, speed=2)] * 2, model)


def main() -> int:
    t0 = time.perf_counter()
    compile_model()
    warm_simulators()
    print(f"model compiled or loaded from numba's cache, simulators warmed: {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
else:
    try:
        warm_simulators()
    except Exception:  # each simulator then loads what it needs, and says what fails
        traceback.print_exc()
