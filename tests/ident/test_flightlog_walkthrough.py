"""docs/flight-logs.md's worked example, run as the page writes it: its console block, taken from
the page (so it cannot drift from what lands), run by a real process from a folder where the
page's path resolves, and what it prints checked against what the page shows, number for number."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

from tests.ident.test_import_walkthrough import same

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "flight-logs.md"


def blocks() -> list[tuple[str, list[str]]]:
    section = PAGE.read_text().split("\n## Worked example", 1)[1].split("\n## ", 1)[0]
    out = []
    for m in re.finditer(r"^```console\n(.*?)^```", section, re.S | re.M):
        lines = m.group(1).rstrip("\n").splitlines()
        assert lines[0].startswith("$ slopelander "), lines[0]
        out.append((lines[0][2:], lines[1:]))
    return out


def test_the_worked_example_prints_what_the_page_shows(tmp_path) -> None:
    (tmp_path / "docs").symlink_to(ROOT / "docs")
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}"}
    found = blocks()
    assert [c.split()[1] for c, _ in found] == ["compare"]
    for command, want in found:
        r = subprocess.run(
            [sys.executable, "-m", "slopelander.cli", *shlex.split(command)[1:]],
            capture_output=True,
            text=True,
            env=env,
            cwd=tmp_path,
            timeout=600,
        )
        assert r.returncode == 0, f"{command}\n{r.stderr}"
        got = r.stdout.rstrip("\n").splitlines()
        assert len(got) == len(want), f"{command}\n{r.stdout}"
        for g, w in zip(got, want, strict=True):
            assert same(g, w, 0.0), f"{command}\n  page:    {w}\n  printed: {g}"
    # and what it wrote: the JSON holds the printed conditions, the plot is a picture
    doc = json.loads((tmp_path / "landing-20deg-compare" / "landing-20deg-landing1.json").read_text())
    assert round(doc["conditions"]["slope_deg"], 1) == 19.4
    assert (tmp_path / "landing-20deg-compare" / "landing-20deg-landing1.png").stat().st_size > 20_000
