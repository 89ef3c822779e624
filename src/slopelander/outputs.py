"""Where a command may write: checked before any work starts, one rule for every command.

The rule: slopelander creates only the output you name -- a file, or for commands that write a
set of files (``map``, ``demo``, ``synth``, ``compare --report``) a folder -- never the folders
above it. A missing parent folder, a file where a folder is wanted (or the reverse) and an
unwritable place are refused with one line before any simulation runs, so no work is lost.
"""

from __future__ import annotations

import os
from pathlib import Path

from slopelander.errors import SlopelanderError


class OutputError(SlopelanderError):
    """An output that cannot be written: found before any work is done."""


def _writable_folder(folder: Path, what: str, path: Path) -> None:
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{what} {path}: {folder} is a file, not a folder")
    if not folder.is_dir():
        raise OutputError(f"{what} {path}: folder {folder} does not exist (create it first)")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: folder {folder} is not writable")


def check_output(path: Path | str | None, what: str) -> None:
    """Refuse an output *file* whose folder is missing or unwritable, or that is a folder."""
    if path is None:
        return
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{what} {path} is a folder; give a file name")
    if path.exists() and not os.access(path, os.W_OK):
        raise OutputError(f"{what} {path}: the file exists and is not writable")
    _writable_folder(path.parent if str(path.parent) else Path("."), what, path)


def check_output_dir(path: Path | str | None, what: str) -> None:
    """Refuse an output *folder* that is a file, unwritable, or whose parent folder is missing."""
    if path is None:
        return
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{what} {path} is a file; give a folder")
    if path.is_dir():
        if not os.access(path, os.W_OK | os.X_OK):
            raise OutputError(f"{what} {path}: folder {path} is not writable")
        return
    _writable_folder(path.parent if str(path.parent) else Path("."), what, path)


def files_changed_since(folder: Path, since: float) -> list[Path]:
    """Files under ``folder`` written at or after ``since`` (a ``time.time()``), sorted."""
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.rglob("*") if p.is_file() and p.stat().st_mtime >= since)
