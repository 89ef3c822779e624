"""A motion-capture take as the readers hand it over: markers in metres, gaps as NaN."""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slopelander.errors import SlopelanderError


class MocapError(SlopelanderError, ValueError):
    """A take that cannot be imported as written: names the file, the take and the field."""

    def __init__(self, path: str | Path, take: str | None, fieldname: str, why: str) -> None:
        where = f"{path}" + (f", take '{take}'" if take else "")
        super().__init__(f"{where}, field '{fieldname}': {why}")
        self.path = str(path)
        self.take = take
        self.field = fieldname


@dataclass(frozen=True)
class RigidBody:
    """A rigid body the capture software solved itself (OptiTrack Motive): its pivot's
    position (frames, 3) in metres, its orientation as quaternions (frames, 4; x, y, z, w),
    and the software's mean marker error per frame (m); NaN where it was not tracked."""

    position: np.ndarray
    quaternion: np.ndarray
    error: np.ndarray


@dataclass(frozen=True)
class Take:
    """One take: every labelled marker's position per frame, in metres, in the capture's axes."""

    path: Path
    name: str
    fmt: str
    """The format and the exporter's layout it was read as (docs/import.md)."""
    rate: float
    """Hz, as the file declares it."""
    labels: tuple[str, ...]
    xyz: np.ndarray
    """(frames, markers, 3), metres; NaN where the marker was not seen."""
    units: str
    """Where the length unit came from, e.g. ``POINT:UNITS = 'mm'``."""
    up: str | None = None
    """The vertical axis the file declares (``+Z``, ``+Y``), or None when it declares none."""
    up_field: str = ""
    bodies: dict[str, RigidBody] = field(default_factory=dict)
    unusable: dict[str, str] = field(default_factory=dict)
    """Rigid bodies in the file that cannot be used, and why."""

    @property
    def frames(self) -> int:
        return int(self.xyz.shape[0])

    def index(self, name: str, what: str) -> int:
        """Column of marker ``name``: its exact label, or the one label whose part after a
        ``Subject:`` prefix is ``name``. A missing one names the closest labels."""
        if name in self.labels:
            return self.labels.index(name)
        tails = [i for i, lab in enumerate(self.labels) if lab.rsplit(":", 1)[-1] == name]
        if len(tails) == 1:
            return tails[0]
        if len(tails) > 1:
            raise MocapError(
                self.path,
                self.name,
                what,
                f"marker '{name}' matches {', '.join(self.labels[i] for i in tails)}",
            )
        close = difflib.get_close_matches(name, self.labels, n=3, cutoff=0.5)
        hint = f"; closest: {', '.join(close)}" if close else f"; the take has {', '.join(self.labels[:12])}"
        raise MocapError(self.path, self.name, what, f"no marker '{name}' in the take{hint}")
