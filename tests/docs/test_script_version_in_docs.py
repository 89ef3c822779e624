"""What the docs say the on-board script announces is what the real script, run in its Lua host,
announces: the version in firmware_params/README.md followed the script from v1 to v3 only by hand."""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "firmware"))
from script_bench import Bench  # noqa: E402 - the firmware tests' bench: the real script in real Lua

DOCS = [ROOT / "README.md", ROOT / "firmware_params" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _announced() -> tuple[str, float]:
    bench = Bench()
    bench.run(1500)
    ready = [t for t in bench.io.sl_texts() if t.endswith(" ready")]
    versions = [v for _, name, v in bench.io.named if name == "SL_VER"]
    assert ready and versions, "the script announced nothing in 1.5 s"
    return ready[0], versions[-1]


def test_the_firmware_readme_quotes_the_scripts_own_announcement() -> None:
    text, version = _announced()
    assert text == f"SL: slopelander script v{version:g} ready"
    readme = (ROOT / "firmware_params" / "README.md").read_text()
    assert f"`{text}`" in readme, f"firmware_params/README.md does not quote {text!r}"


def test_no_document_names_another_script_version_in_its_announcement() -> None:
    text, _ = _announced()
    for doc in DOCS:
        for quoted in re.findall(r"SL: slopelander script v\d+ ready", doc.read_text()):
            assert quoted == text, f"{doc.relative_to(ROOT)} quotes {quoted!r}; the script says {text!r}"
