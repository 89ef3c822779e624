"""The README's test command runs on parallel workers with xdist's ``loadgroup`` (pyproject.toml,
tests/conftest.py): the tests that share a module-scoped fixture run on one worker, in file order,
with the fixture made once; a test that shares one without a group fails, saying why. Checked
on a toy project with this repository's settings (real pytest runs, two workers)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SHARED = """
import os, pytest
{mark}

@pytest.fixture(scope="module")
def vehicle():
    with open(os.environ["MADE"], "a") as f:
        f.write(os.environ.get("PYTEST_XDIST_WORKER", "-") + "\\n")
    return object()

@pytest.mark.parametrize("n", range(4))
def test_shared(vehicle, n):
    with open(os.environ["RAN"], "a") as f:
        f.write(f"{{n}} {{os.environ['PYTEST_XDIST_WORKER']}}\\n")

@pytest.mark.parametrize("n", range(6))
def test_alone(n):
    pass
"""


def _run(root: Path, mark: str) -> subprocess.CompletedProcess:
    shutil.copy(REPO / "pyproject.toml", root / "pyproject.toml")
    (root / "tests").mkdir()
    shutil.copy(REPO / "tests" / "conftest.py", root / "tests" / "conftest.py")
    (root / "tests" / "test_toy.py").write_text(SHARED.format(mark=mark))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "HYPOTHESIS_"))}
    env.update(PYTHONPATH=os.pathsep.join([str(REPO / "src"), str(REPO)]), SLOPELANDER_FORKSERVER="0")
    env.update(MADE=str(root / "made.txt"), RAN=str(root / "ran.txt"), COLUMNS="400")
    cmd = [sys.executable, "-m", "pytest", "-n", "2", "-p", "no:cacheprovider", "-q"]
    return subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=300)


def test_a_group_runs_on_one_worker_in_order_with_its_fixture_made_once(tmp_path: Path) -> None:
    done = _run(tmp_path, 'pytestmark = pytest.mark.xdist_group("toy")')
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    ran = [line.split() for line in (tmp_path / "ran.txt").read_text().splitlines()]
    assert [n for n, _ in ran] == ["0", "1", "2", "3"], (ran, done.stdout[-2000:])
    assert len({w for _, w in ran}) == 1, ran
    assert len((tmp_path / "made.txt").read_text().splitlines()) == 1


def test_a_shared_fixture_without_a_group_fails_its_tests_saying_why(tmp_path: Path) -> None:
    done = _run(tmp_path, "")
    assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]
    why = "the tests that share the fixture 'vehicle' are in no group: they must be in one xdist_group"
    for n in range(4):
        assert f"ERROR tests/test_toy.py::test_shared[{n}] - Failed: {why}" in done.stdout
    assert "4 errors" in done.stdout and "6 passed" in done.stdout and "INTERNALERROR" not in done.stdout
    assert not (tmp_path / "made.txt").exists()
