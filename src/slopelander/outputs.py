"""Where a command may write: checked before any work starts, one rule for every command.

The rule: slopelander creates only the output you name -- a file, or for commands that write a
set of files (``map``, ``demo``, ``synth``, ``compare --out``) a folder -- never the folders
above it. A missing parent folder, a file where a folder is wanted (or the reverse) and an
unwritable place are refused with one line before any simulation runs, so no work is lost.

Writability is tried, not read from the permission bits: root passes every ``os.access`` check,
yet cannot create a file in ``/proc`` or on a read-only mount.
"""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path

from slopelander.errors import SlopelanderError


class OutputError(SlopelanderError):
    """An output that cannot be written: found before any work is done."""


def _try_write(folder: Path, what: str, path: Path, *, folder_wanted: bool = False) -> None:
    """Create (and remove) a file -- or a folder, where a folder is what will be written -- in
    ``folder``: the one check that holds for root, /proc and read-only mounts alike."""
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: folder {folder} is not writable")
    try:
        if folder_wanted:
            os.rmdir(tempfile.mkdtemp(prefix=".slopelander-check-", dir=folder))
        else:
            with tempfile.NamedTemporaryFile(prefix=".slopelander-check-", dir=folder):
                pass
    except OSError as exc:
        # /proc says "no such file" for any name: the folder is there, it just takes no files
        reason = "" if exc.errno == errno.ENOENT else f" ({exc.strerror or type(exc).__name__})"
        raise OutputError(f"{what} {path}: folder {folder} is not writable{reason}") from None


def _writable_folder(folder: Path, what: str, path: Path, *, folder_wanted: bool = False) -> None:
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{what} {path}: {folder} is a file, not a folder")
    if not folder.is_dir():
        raise OutputError(f"{what} {path}: folder {folder} does not exist (create it first)")
    _try_write(folder, what, path, folder_wanted=folder_wanted)


def check_output(path: Path | str | None, what: str) -> None:
    """Refuse an output *file* whose folder is missing or unwritable, or that is a folder."""
    if path is None:
        return
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{what} {path} is a folder; give a file name")
    if path.is_file():
        try:
            with path.open("ab"):  # appends nothing: the file is left as it is
                pass
        except OSError as exc:
            reason = exc.strerror or type(exc).__name__
            raise OutputError(f"{what} {path}: the file exists and is not writable ({reason})") from None
    _writable_folder(path.parent if str(path.parent) else Path("."), what, path)


def check_output_dir(path: Path | str | None, what: str) -> None:
    """Refuse an output *folder* that is a file, unwritable, or whose parent folder is missing."""
    if path is None:
        return
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{what} {path} is a file; give a folder")
    if path.is_dir():
        _try_write(path, what, path)
        return
    _writable_folder(path.parent if str(path.parent) else Path("."), what, path, folder_wanted=True)


def files_changed_since(folder: Path, since: float) -> list[Path]:
    """Files under ``folder`` written at or after ``since`` (a ``time.time()``), sorted."""
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.rglob("*") if p.is_file() and p.stat().st_mtime >= since)
