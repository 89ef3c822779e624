"""Run a script on the real MicroPython (``SLOPELANDER_MICROPYTHON``) with the firmware and the
shared ``wire`` module on its path; the tests that need it skip, saying why, without it."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BINARY = os.environ.get("SLOPELANDER_MICROPYTHON")
needs_micropython = pytest.mark.skipif(
    not BINARY,
    reason="SLOPELANDER_MICROPYTHON is not set: it names a MicroPython unix-port binary "
    "(docs/legs-build.md says how to build one); .ci/run sets it when one is beside the checkout",
)
HEAP = "192K"  # what slopelander_sitl.legboard gives the firmware: about a Pico's free heap


def run(script: str, stdin: str = "", timeout: float = 300.0) -> list:
    """Run ``script`` on MicroPython; every line it prints is one JSON value."""
    prelude = (
        "import sys\n"
        f"sys.path.append({str(ROOT / 'src' / 'slopelander' / 'legs')!r})\n"
        f"sys.path.append({str(ROOT / 'firmware' / 'legboard')!r})\n"
    )
    done = subprocess.run(
        [BINARY, "-X", f"heapsize={HEAP}", "-c", prelude + script],
        input=stdin,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    return [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
