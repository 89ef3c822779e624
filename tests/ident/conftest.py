import os
import subprocess
import sys
from pathlib import Path

import pytest

from slopelander.model import Model

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def model() -> Model:
    return Model.default()


def slopelander(*args: str) -> subprocess.CompletedProcess:
    """``slopelander ARGS`` as a user runs it: a real process on this checkout's code."""
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}"}
    cmd = [sys.executable, "-m", "slopelander.cli", *args]
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
