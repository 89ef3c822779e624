"""The README and the docs say what the code does today: each checked example is run and its
printed lines compared with the page (benchmarks/figures.py), every documented `slopelander`
command parses, and the README stays a short page that points to every doc."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
import figures  # noqa: E402 - the checker the docs name

README = (ROOT / "README.md").read_text()
EXAMPLES = [e for page in figures.RUN_PAGES for e in figures.examples(page)]


def test_there_are_checked_examples() -> None:
    assert {e.command.split()[1] for e in EXAMPLES} >= {"simulate", "lookup"}


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda e: e.command)
def test_each_checked_example_prints_what_the_page_says(example) -> None:
    assert figures.differences(example, figures.run(example.command)) == []


@pytest.mark.parametrize("page", figures.PAGES, ids=lambda p: p.name)
def test_every_documented_command_parses(page: Path) -> None:
    problems = [
        f"{n}: {c}: {why}" for n, c in figures.command_lines(page) if (why := figures.parse_problem(c))
    ]
    assert problems == []


def test_the_checker_catches_a_stale_line_and_a_renamed_option() -> None:
    example = EXAMPLES[0]
    stale = figures.Example(example.page, example.command, [*example.printed[:-1], "at rest after: 9 s"], 0)
    assert figures.differences(stale, example.printed) != []
    assert figures.parse_problem("slopelander simulate --slope 35 --no-such-option 2") is not None
    assert figures.parse_problem("slopelander simulate --slope 35 --speed 2.7") is None


def test_the_readme_keeps_the_ci_command_and_stays_short() -> None:
    command = 'python3 -m pip install -e ".[test]" && python3 -m slopelander_sitl.warm && python3 -m pytest'
    assert f"\n    {command}\n" in README
    assert (ROOT / ".ci" / "run").read_text().rstrip().endswith(f"\n{command}")
    assert len(re.sub(r"\(docs/[^)]*\)|\(firmware_params/[^)]*\)", "", README).split()) < 950


def test_the_readme_lists_every_doc_page() -> None:
    listed = set(re.findall(r"\]\(docs/([\w-]+\.md)\)", README.split("## Where to read on")[1]))
    assert listed == {p.name for p in (ROOT / "docs").glob("*.md")}


def test_the_readme_explains_its_jargon() -> None:
    glossary = README.split("## Glossary")[1]
    for word in ("FSA", "RVT", "under_used", "table cell", "NRMSE", "Cut height", "Preset"):
        assert word in glossary, word
