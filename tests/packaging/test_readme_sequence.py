"""The README's two commands in a row on a fresh checkout: ``slopelander demo`` leaves its folder
in the repository root, and the next ``pip install -e ".[test]"`` must still work (and so must the
ArduPilot section's ``sitl-run/``); the output folders stay out of ``git status``."""

from __future__ import annotations

import shutil
import subprocess
import sys
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

# What the commands leave in the repository root: the demo's files and the ArduPilot section's
# SITL folder (README "Using it"/ArduPilot sections).
OUTPUTS = {
    "slopelander-demo": ["flight.tlog", "transitions.jsonl", "result.json", "flight.png"],
    "sitl-run": ["scripts/slopelander.lua", "arducopter.log", "eeprom.bin"],
}


def _fresh_checkout(dest: Path) -> None:
    """The files a clone of the current tree would hold (tracked and new, not ignored)."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        capture_output=True,
        check=True,
    ).stdout.split(b"\0")
    for name in filter(None, (n.decode() for n in listed)):
        src = REPO / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)


def _leave_outputs(root: Path) -> None:
    for folder, files in OUTPUTS.items():
        for name in files:
            (root / folder / name).parent.mkdir(parents=True, exist_ok=True)
            (root / folder / name).write_bytes(b"output\n")


@pytest.mark.slow
def test_install_after_the_demo_left_its_folders_in_the_root(tmp_path: Path) -> None:
    clone = tmp_path / "slopelander"
    _fresh_checkout(clone)
    _leave_outputs(clone)
    env_dir = tmp_path / "venv"
    # The system's packages stand in for the dependencies (--no-deps), so the install takes seconds;
    # the build itself runs as the README's command runs it (pyproject's build backend, isolated),
    # and with it the package discovery that the output folders broke.
    venv.EnvBuilder(with_pip=False, system_site_packages=True).create(env_dir)
    py = env_dir / "bin" / "python"
    install = subprocess.run(
        [str(py), "-m", "pip", "install", "--no-deps", "-e", ".[test]"],
        cwd=clone,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert install.returncode == 0, install.stdout[-2000:] + install.stderr[-3000:]
    where = subprocess.run(
        [str(py), "-c", "import slopelander.cli, slopelander_sitl.vehicle; print(slopelander.cli.__file__)"],
        cwd=env_dir,  # not next to the clone's folder, which would shadow the installed package
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert where.returncode == 0, where.stderr[-2000:]
    assert Path(where.stdout.strip()).is_relative_to(clone / "src")


def test_the_output_folders_are_ignored_by_git() -> None:
    paths = [f"{folder}/{name}" for folder, files in OUTPUTS.items() for name in files]
    ignored = subprocess.run(
        ["git", "check-ignore", "--no-index", *paths], cwd=REPO, capture_output=True, text=True
    ).stdout.split()
    assert sorted(ignored) == sorted(paths)


def test_the_packages_found_are_exactly_the_source_packages(tmp_path: Path) -> None:
    """Package discovery finds every package with an ``__init__.py`` under src/slopelander and
    src/slopelander_sitl, and nothing else, whatever folders sit in the root."""
    clone = tmp_path / "slopelander"
    _fresh_checkout(clone)
    _leave_outputs(clone)
    (clone / "slopelander-demo-2").mkdir()
    (clone / "sitlish").mkdir()
    (clone / "sitlish" / "__init__.py").write_text("")
    code = (
        "import json, warnings; warnings.simplefilter('ignore')\n"
        "from setuptools.config.pyprojecttoml import read_configuration\n"
        "print(json.dumps(read_configuration('pyproject.toml')['tool']['setuptools']['packages']))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=clone, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-2000:]
    import json

    found = set(json.loads(out.stdout))
    expected = {
        ".".join(p.parent.relative_to(base).parts)
        for base, top in ((REPO / "src", "slopelander"), (REPO / "src", "slopelander_sitl"))
        for p in (base / top).rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    assert found == expected
