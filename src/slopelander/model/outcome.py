"""Outcome classes of a landing (paper Sec. V-A) and the criteria that separate them."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np


class Outcome(IntEnum):
    """Landing outcome, ordered from best to worst (a landing takes the worst it reached)."""

    IDEAL = 0
    """Landed, at least one leg used more than 40 % of its travel, none hit its end."""
    UNDER_USED = 1
    """Landed, but no leg compressed more than 40 %: the friction was set too high."""
    END_OF_TRAVEL = 2
    """Landed, but a leg ran into its end-of-travel stop (harder impact, risk of damage)."""
    SLID = 3
    """Slid more than 1 m down the slope, or still moving at the end of the horizon."""
    JOINT_TOUCH = 4
    """A leg joint (or a rotor) touched the surface."""
    FLIP = 5
    """Pitch passed 80 deg: the vehicle tipped over."""
    DAMAGED = 6
    """Stock rigid gear only: a foot's impact load passed ``rigid_load_limit`` (the gear broke)."""

    def __str__(self) -> str:
        """The name a person reads (``ideal``, ``end_of_travel``); ``int()`` gives the code."""
        return self.name.lower()

    def __format__(self, spec: str) -> str:
        return format(str(self), spec)

    @property
    def success(self) -> bool:
        return self in (Outcome.IDEAL, Outcome.UNDER_USED, Outcome.END_OF_TRAVEL)

    @property
    def label(self) -> str:
        return OUTCOME_LABELS[self]


OUTCOME_LABELS = {
    Outcome.IDEAL: "ideal",
    Outcome.UNDER_USED: "under-used (<40 % compression)",
    Outcome.END_OF_TRAVEL: "end of travel",
    Outcome.SLID: "slid >1 m or still moving",
    Outcome.JOINT_TOUCH: "joint touched the surface",
    Outcome.FLIP: "flipped",
    Outcome.DAMAGED: "gear damaged (impact load over its limit)",
}

# The paper's colour code (Fig. 8): green, blue, orange, white, light grey, dark grey -- except
# that "slid" is light purple here, not white: a white cell reads as missing data. "Damaged" is
# not one of the paper's classes: dark red, unlike any of them.
OUTCOME_COLORS = {
    Outcome.IDEAL: "#2ca02c",
    Outcome.UNDER_USED: "#1f77b4",
    Outcome.END_OF_TRAVEL: "#ff7f0e",
    Outcome.SLID: "#c5b0d5",
    Outcome.JOINT_TOUCH: "#c7c7c7",
    Outcome.FLIP: "#555555",
    Outcome.DAMAGED: "#b2182b",
}


@dataclass(frozen=True)
class OutcomeCriteria:
    """Thresholds of Sec. V-A, plus the settling test used to stop a landing early."""

    horizon: float = 2.0
    """Seconds simulated after impact at most."""
    slide_limit: float = 1.0
    """Metres of travel along the slope that count as sliding away."""
    underused_fraction: float = 0.4
    flip_pitch_deg: float = 80.0
    settle_speed: float = 0.02
    """m/s: below this (and the rate below), with every foot stuck, the vehicle is at rest."""
    settle_rate_dps: float = 2.0
    settle_time: float = 0.15
    """Seconds the rest condition must hold before a landing is called settled."""


RESULT_FIELDS: tuple[str, ...] = (
    "outcome",
    "compression_up",
    "compression_down",
    "slide",
    "final_pitch_deg",
    "min_pitch_deg",
    "settle_time",
    "t_end",
)
"""Columns of the batch path's result: outcome code, peak compression fraction of the
uphill and downhill joints, slide distance along the slope (m, + downhill), final pitch and
the pitch furthest toward downhill (deg, negative = nose toward downhill, whatever the sign
of the slope), time from impact to rest (s, NaN if it never settled), simulated time."""

RESULT_DTYPE = np.dtype([(n, np.int64 if n == "outcome" else np.float64) for n in RESULT_FIELDS])
"""The batch result: ``outcome`` is the integer code (:class:`Outcome`), for machines; people read
:func:`outcome_names` of it."""

OUTCOME_NAMES: tuple[str, ...] = tuple(str(o) for o in Outcome)


def outcome_names(codes: np.ndarray) -> np.ndarray:
    """The outcome names (``"ideal"``, ``"flip"``, ...) of an array of outcome codes, same shape."""
    codes = np.asarray(codes)
    return np.asarray(OUTCOME_NAMES)[codes.astype(int)]
