"""One style for the whole tree: ``ruff check .`` and ``ruff format --check .`` pass (CI runs this).

Skipped only where ruff is not installed; the test extra installs it.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUFF = shutil.which("ruff")

pytestmark = pytest.mark.skipif(RUFF is None, reason="ruff is not installed (it is in the test extra)")


@pytest.mark.parametrize("args", [["check", "."], ["format", "--check", "."]], ids=["lint", "format"])
def test_ruff_passes(args: list[str]) -> None:
    done = subprocess.run([str(RUFF), *args], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"ruff {' '.join(args)}:\n{done.stdout}{done.stderr}"


def test_the_installed_core_never_imports_the_simulator() -> None:
    """``slopelander`` is the product a vehicle runs; the simulator (``slopelander_sitl``)
    builds on it and adds its commands and benches through entry points, never the other way."""
    import ast
    from pathlib import Path

    core = Path(__file__).resolve().parents[1] / "src" / "slopelander"
    found = []
    for path in core.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            found += [
                f"{path.relative_to(core)}: {n}" for n in names if n.split(".")[0] == "slopelander_sitl"
            ]
    assert not found, found
