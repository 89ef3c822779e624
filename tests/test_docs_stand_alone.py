"""The documentation cites only files the repository has: a user has nothing else."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")])
LINK = re.compile(r"\]\(([^)\s]+)\)")
CODE_PATH = re.compile(r"`((?:docs|src|benchmarks|tests|firmware_params|firmware)/[\w./-]+)`")


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_cited_file_exists(doc: Path) -> None:
    text = doc.read_text()
    missing = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        path = (doc.parent / target.split("#")[0]).resolve()
        if not path.exists():
            missing.append(target)
    for target in CODE_PATH.findall(text):
        if not (ROOT / target.rstrip(".")).exists() and "*" not in target and "<" not in target:
            missing.append(target)
    assert not missing, f"{doc.name} cites {missing}"


@pytest.mark.parametrize(
    "doc", [*DOCS, ROOT / "src/slopelander/model/default_parameters.yaml"], ids=lambda p: p.name
)
def test_no_document_points_outside_the_repository(doc: Path) -> None:
    text = doc.read_text()
    for outside in ("DESIGN.md", "FIRMWARE-CONTRACT.md", "STYLE.md", "../shared", "/work/"):
        assert outside not in text, f"{doc.name} refers to {outside}, which a user does not have"
