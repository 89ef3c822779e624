"""Fixtures of the firmware tests; the pieces they are made of live in script_bench.py (a module
with its own name, so that these tests import it whatever else pytest collects first).

The ArduPilot reference data (parameter documentation and Lua binding names, see the README's
"Running the tests") is found through $SLOPELANDER_ARDUPILOT_REFERENCE, else in a
``shared/reference`` folder beside the checkout or above it. Without it the tests that need it
skip and say why; under CI=true they fail, so a CI run cannot go green without checking the
parameter files and the script's bindings."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from script_bench import bench  # noqa: F401 - fixture, registered by import

REPO = Path(__file__).resolve().parents[2]
ENV = "SLOPELANDER_ARDUPILOT_REFERENCE"
NEEDED = ("ardupilot-copter-params.tsv", "ardupilot-lua-bindings.txt")


def find_reference(repo: Path = REPO, environ: dict[str, str] | None = None) -> tuple[Path | None, str]:
    """The reference folder and, when there is none, the one-line reason why."""
    environ = os.environ if environ is None else environ
    named = environ.get(ENV)
    if named:
        path = Path(named)
        missing = [f for f in NEEDED if not (path / f).is_file()]
        if missing:
            return None, f"{ENV}={named} lacks {', '.join(missing)}"
        return path, ""
    for folder in repo.parents:
        path = folder / "shared" / "reference"
        if all((path / f).is_file() for f in NEEDED):
            return path, ""
    return None, (f"ArduPilot reference data not found: set {ENV} to a folder holding {' and '.join(NEEDED)}")


@pytest.fixture
def reference() -> Path:
    path, reason = find_reference()
    if path is None:
        if os.environ.get(ENV) or os.environ.get("CI", "").lower() == "true":
            pytest.fail(reason, pytrace=False)
        print(reason)
        pytest.skip(reason)
    return path
