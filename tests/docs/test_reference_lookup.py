"""The firmware tests find the ArduPilot reference data without being told, and a CI run without it
fails instead of skipping (a skipped check of the parameter files is a green run that checked
nothing). Each case runs the real firmware tests in a fresh pytest process on a copy of the
checkout placed where no ``shared/reference`` lies above it."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "tests" / "firmware"


def _reference() -> Path | None:
    for folder in ROOT.parents:
        if (folder / "shared" / "reference" / "ardupilot-copter-params.tsv").is_file():
            return folder / "shared" / "reference"
    named = os.environ.get("SLOPELANDER_ARDUPILOT_REFERENCE")
    return Path(named) if named else None


@pytest.fixture
def lone_checkout(tmp_path: Path) -> Path:
    """The firmware tests and the files they read, in a folder with nothing above it."""
    repo = tmp_path / "checkout"
    shutil.copytree(FIRMWARE, repo / "tests" / "firmware", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "firmware_params", repo / "firmware_params")
    (repo / "pytest.ini").write_text("[pytest]\naddopts = -ra -p no:cacheprovider\n")
    return repo


def _counts(run: subprocess.CompletedProcess) -> dict[str, int]:
    """pytest's last line, "5 passed, 9 skipped in 1.0s", as {"passed": 5, "skipped": 9}."""
    last = run.stdout.strip().splitlines()[-1]
    return {word: int(n) for n, word in re.findall(r"(\d+) (passed|skipped|failed|errors?)", last)}


def _run(repo: Path, **env: str) -> subprocess.CompletedProcess:
    clean = {k: v for k, v in os.environ.items() if k not in ("CI", "SLOPELANDER_ARDUPILOT_REFERENCE")}
    clean["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), str(ROOT)])
    tests = ["tests/firmware/test_script_bindings.py", "tests/firmware/test_parameter_files.py"]
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", *tests],
        cwd=repo,
        env={**clean, **env},
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_without_the_reference_the_tests_skip_and_say_how_to_give_it(lone_checkout: Path) -> None:
    run = _run(lone_checkout)
    assert run.returncode == 0, run.stdout + run.stderr
    assert _counts(run).get("skipped", 0) >= 8 and "failed" not in _counts(run)
    assert "set SLOPELANDER_ARDUPILOT_REFERENCE to a folder holding" in run.stdout


def test_under_ci_a_missing_reference_fails(lone_checkout: Path) -> None:
    skipped = _counts(_run(lone_checkout))["skipped"]
    run = _run(lone_checkout, CI="true")
    assert run.returncode == 1, run.stdout + run.stderr
    counts = _counts(run)  # a failing fixture is counted as an error
    assert counts.get("failed", 0) + counts.get("errors", 0) == skipped and "skipped" not in counts
    assert "ArduPilot reference data not found" in run.stdout


def test_a_named_folder_without_the_files_fails(lone_checkout: Path, tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    run = _run(lone_checkout, SLOPELANDER_ARDUPILOT_REFERENCE=str(empty))
    assert run.returncode == 1, run.stdout + run.stderr
    assert "lacks ardupilot-copter-params.tsv, ardupilot-lua-bindings.txt" in run.stdout


def test_the_named_reference_runs_the_eight_checks(lone_checkout: Path) -> None:
    ref = _reference()
    if ref is None:
        pytest.skip("no ArduPilot reference data on this machine to run the checks against")
    run = _run(lone_checkout, CI="true", SLOPELANDER_ARDUPILOT_REFERENCE=str(ref))
    assert run.returncode == 0, run.stdout + run.stderr
    assert set(_counts(run)) == {"passed"}, run.stdout


def test_this_checkout_finds_the_reference_above_it_without_the_variable() -> None:
    ref = _reference()
    if ref is None or not any((p / "shared" / "reference").is_dir() for p in ROOT.parents):
        pytest.skip("no shared/reference above this checkout")
    spec = importlib.util.spec_from_file_location("firmware_conftest", FIRMWARE / "conftest.py")
    firmware_conftest = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(FIRMWARE))
    try:
        spec.loader.exec_module(firmware_conftest)
    finally:
        sys.path.remove(str(FIRMWARE))
    found, reason = firmware_conftest.find_reference(environ={})
    assert found == ref and reason == ""
