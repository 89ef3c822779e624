"""docs/import.md's worked example, run as the page writes it: its console blocks, taken from
the page (so it cannot drift from what lands), each command run by a real process from a folder
where the page's paths resolve, and what it prints checked against what the page shows."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "import.md"
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
SEARCHING = ("diagnose", "fit", "steps")
"""Commands whose numbers come from a stochastic search: compared more loosely (another
machine's floating point may lead CMA-ES elsewhere); their words must still be the page's."""

pytestmark = pytest.mark.slow


def blocks() -> list[tuple[str, list[str]]]:
    section = PAGE.read_text().split("\n## Worked example", 1)[1].split("\n## ", 1)[0]
    out = []
    for m in re.finditer(r"^```console\n(.*?)^```", section, re.S | re.M):
        lines = m.group(1).rstrip("\n").splitlines()
        assert lines[0].startswith("$ slopelander "), lines[0]
        out.append((lines[0][2:], lines[1:]))
    return out


def documented_exit() -> int:
    """The exit code the page gives diagnose ("It exits N"), and the verdict the code stands for."""
    from slopelander.commands.diagnose import DIAGNOSE_EXIT

    m = re.search(r"It exits (\d) \(", PAGE.read_text())
    assert m, "the page no longer says diagnose's exit code"
    assert int(m.group(1)) in DIAGNOSE_EXIT.values()
    return int(m.group(1))


def same(got: str, want: str, rel: float) -> bool:
    """The same words, and each number within ``rel`` of the page's (or two units of its last
    printed digit)."""
    if NUMBER.sub("#", got) != NUMBER.sub("#", want):
        return False
    for g, w in zip(NUMBER.findall(got), NUMBER.findall(want), strict=True):
        digits = len(w.split(".")[1].split("e")[0]) if "." in w else 0
        if abs(float(g) - float(w)) > max(rel * abs(float(w)), 2.0 * 10**-digits):
            return False
    return True


def test_the_worked_example_prints_what_the_page_shows(tmp_path):
    (tmp_path / "docs").symlink_to(ROOT / "docs")
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}"}
    found = blocks()
    assert [c.split()[1] for c, _ in found] == ["import", "compare", "diagnose", "steps"]
    for command, want in found:
        argv = shlex.split(command)
        r = subprocess.run(
            [sys.executable, "-m", "slopelander.cli", *argv[1:]],
            capture_output=True,
            text=True,
            env=env,
            cwd=tmp_path,
            timeout=600,
        )
        # diagnose exits with its verdict's code (commands/diagnose.py DIAGNOSE_EXIT): the one the page says
        code = documented_exit() if argv[1] == "diagnose" else 0
        assert r.returncode == code, f"{command}: exit {r.returncode}, the page says {code}\n{r.stderr}"
        got = r.stdout.rstrip("\n").splitlines()
        assert len(got) == len(want), f"{command}\n{r.stdout}"
        rel = 0.25 if argv[1] in SEARCHING else 0.0
        for g, w in zip(got, want, strict=True):
            assert same(g, w, rel), f"{command}\n  page:    {w}\n  printed: {g}"
