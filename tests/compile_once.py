"""Compile the model into numba's cache once, beside the suite's first tests.

On a fresh checkout nothing is compiled yet, and every process that needs the model before one of
them has written it to the cache compiles it too: both workers, both workers' simulator zygotes and
the commands the tests start, at once, about 50 s of CPU each (the stepper 35 s, a landing and a
batch of landings after it; ``python3 benchmarks/first_compile.py``). Run once here, the others load
it. With the cache warm this costs the few seconds of loading it.

The compile takes one core. So it runs in the background (:class:`BackgroundCompile`) while the
workers start and run the tests that need no model (``model_free`` modules, handed out first); a
test that needs the model waits for it (:func:`wait_for_model`, from tests/conftest.py).
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
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


def _command() -> tuple[list[str], dict[str, str]]:
    import slopelander

    # the package this run tests (pytest's pythonpath), not whichever one is installed: it is the
    # one whose cache the workers read
    src = str(Path(slopelander.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [src, os.environ.get("PYTHONPATH")]))}
    return [sys.executable, "-W", "ignore", "-c", _PROBE], env


class BackgroundCompile:
    """Compiling, or loading, the model in a process of its own, started now, in the background.
    When it ends, ``flag`` holds ``ok <seconds>`` or ``failed <status>`` and the compiler's error
    (written whole, then renamed into place, so a reader never sees half of it)."""

    def __init__(self, flag: Path) -> None:
        self.flag = flag
        self.seconds: float | None = None
        cmd, env = _command()
        self._t0 = time.monotonic()
        quiet, pipe = subprocess.DEVNULL, subprocess.PIPE
        self._proc = subprocess.Popen(cmd, stdin=quiet, stdout=quiet, stderr=pipe, text=True, env=env)
        self._thread = threading.Thread(target=self._wait, daemon=True)
        self._thread.start()

    def _wait(self) -> None:
        err = self._proc.stderr.read() if self._proc.stderr else ""
        status = self._proc.wait()
        self.seconds = time.monotonic() - self._t0
        text = f"ok {self.seconds:.1f}\n" if status == 0 else f"failed {status}\n{err[-4000:]}"
        tmp = self.flag.with_suffix(".tmp")
        try:
            tmp.write_text(text)
            tmp.replace(self.flag)
        except OSError as exc:  # the waiting tests see the folder gone
            sys.stderr.write(f"the model's compile ended ({text.split()[0]}) but its flag: {exc}\n")

    def stop(self) -> None:
        """End the compile if it still runs (the session ended first), and remove the flag."""
        if self._proc.poll() is None:
            self._proc.kill()
        self._thread.join(timeout=10)
        for p in (self.flag, self.flag.with_suffix(".tmp")):
            p.unlink(missing_ok=True)


#: s a test waits for the compile: a fresh checkout's takes about a minute, more on a busy machine
WAIT_S = 900.0


def wait_for_model(flag: Path, timeout_s: float = WAIT_S) -> str | None:
    """Wait until the background compile has ended; None when it compiled, else why not."""
    deadline = time.monotonic() + timeout_s
    while not flag.exists():
        if not flag.parent.is_dir():  # removed under the run: no flag can come
            return f"the model's compile flag's folder {flag.parent} is gone"
        if time.monotonic() > deadline:
            return f"the model's compile did not end within {timeout_s:g} s"
        time.sleep(0.1)
    text = flag.read_text()
    if text.startswith("ok"):
        return None
    return "the model does not compile: " + text.split("\n", 1)[-1].strip()
