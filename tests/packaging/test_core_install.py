"""A companion computer installs only what it flies with: the core, without the simulator."""

from __future__ import annotations

import subprocess
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

CHECK = """
import importlib.util, sys
import slopelander.controller.runner, slopelander.controller.link, slopelander.controller.table
import slopelander.legs.driver, slopelander.commands.land
heavy = [m for m in ("numba", "scipy", "matplotlib", "lupa", "cma") if importlib.util.find_spec(m)]
assert not heavy, f"the core installed {heavy}"
assert not any(m.split(".")[0] in ("numba", "scipy", "matplotlib") for m in sys.modules)
table = slopelander.controller.table.LookupTable.load(slopelander.controller.table.DEFAULT_TABLE)
print("ok", table.lookup(35.0, 1.5))
"""


@pytest.mark.slow
def test_the_core_installs_alone_and_flies_the_controller(tmp_path: Path) -> None:
    env_dir = tmp_path / "core"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    py = env_dir / "bin" / "python"
    # --no-compile: byte-compiling every installed module (pymavlink's dialects are most of it)
    # was 15 of the install's 25 CPU-s; the check below compiles what it imports
    install = subprocess.run(
        [str(py), "-m", "pip", "install", "--quiet", "--no-compile", str(REPO)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert install.returncode == 0, install.stderr[-3000:]
    check = subprocess.run([str(py), "-c", CHECK], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert check.returncode == 0, check.stderr[-3000:]
    assert check.stdout.startswith("ok")
    cli = env_dir / "bin" / "slopelander"
    help_out = subprocess.run([str(cli), "--help"], capture_output=True, text=True, timeout=60)
    assert help_out.returncode == 0 and "land" in help_out.stdout and "needs: pip install" in help_out.stdout
    sim = subprocess.run([str(cli), "simulate"], capture_output=True, text=True, timeout=60)
    assert sim.returncode == 1
    assert "needs the simulation extra" in sim.stderr and "Traceback" not in sim.stderr
