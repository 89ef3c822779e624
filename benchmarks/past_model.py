"""A past commit's landing model, importable beside today's in the same process.

A speed benchmark on this machine means something only as a ratio measured in one run (the
machine's speed moves 3-4x with its hours). To time today's integrator against the one of an
earlier commit, the earlier ``src/slopelander`` (its ``__init__``, ``errors`` and ``model``) is
extracted from git into a cache directory under another package name
(``slopelander_at_<commit>``), its own imports renamed to match. Nothing is copied into the
repository; numba caches the old integrator's compiled code beside the extracted files, so it
compiles once per machine.

    from past_model import load_past_model
    old = load_past_model("67501ca")       # the package's ``model`` module
    old.simulate_batch(conds, old.Model.default())
"""

from __future__ import annotations

import importlib
import io
import os
import re
import subprocess
import sys
import tarfile
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[1]
_PARTS = ("src/slopelander/__init__.py", "src/slopelander/errors.py", "src/slopelander/model")
_NAME = re.compile(r"\bslopelander\.(?=(?:model|errors)(?:[.\s\"',)]|$))")
"""The package's own name where code imports it (not in a file format's schema string)."""


def cache_root() -> Path:
    root = os.environ.get("SLOPELANDER_CACHE_DIR") or Path.home() / ".cache" / "slopelander"
    return Path(root) / "past-models"


def _resolve(commit: str) -> str:
    try:
        out = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "--verify", f"{commit}^{{commit}}"],
            check=True,
            capture_output=True,
            text=True,
        )
    except (OSError, subprocess.CalledProcessError) as e:
        why = getattr(e, "stderr", "") or e
        raise SystemExit(
            f"past_model: no commit {commit!r} in {REPO} (a git checkout is needed): {why}"
        ) from None
    return out.stdout.strip()


def _extract(full: str, dest: Path) -> None:
    """``git archive`` of the model's files at ``full`` into ``dest``, renamed."""
    package = dest.name
    tar = subprocess.run(["git", "-C", str(REPO), "archive", full, *_PARTS], check=True, capture_output=True)
    tmp = dest.with_name(f"{package}.{os.getpid()}.tmp")
    with tarfile.open(fileobj=io.BytesIO(tar.stdout)) as tf:
        for m in tf.getmembers():
            if not m.isfile():
                continue
            rel = Path(m.name).relative_to("src/slopelander")
            data = tf.extractfile(m).read()  # type: ignore[union-attr]
            if rel.suffix == ".py":
                data = _NAME.sub(f"{package}.", data.decode()).encode()
            out = tmp / rel
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_bytes(data)
    tmp.replace(dest)


def load_past_model(commit: str) -> ModuleType:
    """The ``model`` package of ``commit`` (any name git resolves), imported under
    ``slopelander_at_<12 hex digits>``."""
    full = _resolve(commit)
    package = f"slopelander_at_{full[:12]}"
    root = cache_root()
    dest = root / package
    if not dest.is_dir():
        root.mkdir(parents=True, exist_ok=True)
        _extract(full, dest)
    if str(root) not in sys.path:
        sys.path.append(str(root))
    return importlib.import_module(f"{package}.model")
