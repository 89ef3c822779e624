"""Friction torque ↔ motor current, per leg, from a calibration file.

The board regulates current, the landing wants torque: this module turns one into the other
through each leg's measured curve (paper Fig. 3). The interpolation is piecewise linear, which
keeps a monotone table monotone and needs no scipy, because it runs on the companion computer.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import yaml

from slopelander.legs.errors import AngleOutOfRange, CalibrationError, TorqueOutOfRange
from slopelander.legs.messages import MAX_ANGLE_CDEG, N_LEGS

PROVENANCES = ("measured", "derived", "assumed")
TORQUE_UNITS = ("N*m", "N·m", "Nm", "N m")
DEFAULT_FILE = "default_calibration.yaml"
PROTOCOL_ANGLE_RANGE_DEG = (0.0, MAX_ANGLE_CDEG / 100.0)


@dataclass(frozen=True)
class LegCurve:
    """One leg's table: ``torque_nm[k]`` at ``current_ma[k]``."""

    current_ma: tuple[float, ...]
    torque_nm: tuple[float, ...]

    @property
    def max_torque_nm(self) -> float:
        return self.torque_nm[-1]

    @property
    def min_torque_nm(self) -> float:
        return self.torque_nm[0]

    def torque(self, current_ma: float) -> float:
        """Torque at a current; clamped to the table's ends outside it."""
        xs, ys = self.current_ma, self.torque_nm
        if current_ma <= xs[0]:
            return ys[0]
        if current_ma >= xs[-1]:
            return ys[-1]
        k = bisect.bisect_right(xs, current_ma) - 1
        return ys[k] + (current_ma - xs[k]) * (ys[k + 1] - ys[k]) / (xs[k + 1] - xs[k])

    def current_for(self, torque_nm: float) -> float:
        """The current at which the rising curve reaches ``torque_nm`` (the inverse).

        On a flat stretch the end of the stretch is returned: the lowest current of the
        rising part with that torque. Outside the table: ``ValueError``.
        """
        xs, ys = self.current_ma, self.torque_nm
        if not ys[0] <= torque_nm <= ys[-1] or math.isnan(torque_nm):
            raise ValueError(torque_nm)
        k = max(bisect.bisect_left(ys, torque_nm) - 1, 0)
        while ys[k + 1] < torque_nm or ys[k + 1] == ys[k]:
            if k + 2 == len(ys):
                return xs[-1]
            k += 1
        return xs[k] + (torque_nm - ys[k]) * (xs[k + 1] - xs[k]) / (ys[k + 1] - ys[k])


@dataclass(frozen=True)
class Calibration:
    """The curves of all four legs and where they came from."""

    legs: tuple[LegCurve, ...]
    provenance: str
    source: str
    #: the leg angles (deg below the horizontal, fully extended at 37.5) the legs can be set to and held at
    angle_range_deg: tuple[float, float] = PROTOCOL_ANGLE_RANGE_DEG
    #: the board the curve was measured on (16 hex digits), None when the file names none
    board_id: str | None = None

    def check_board(self, board_id: str) -> None:
        """Refuse a curve measured on another board (:class:`CalibrationError`): its motors,
        screws and stacks are not these, so its torques would be wrong on every leg."""
        if self.board_id is not None and board_id and self.board_id != board_id.lower():
            raise CalibrationError(
                self.source,
                "board_id",
                f"measured on leg board {self.board_id}, but the board connected is {board_id}: "
                "use that board's calibration, or measure this one (slopelander legs calibrate)",
            )

    def current_for(self, leg: int, torque_nm: float) -> int:
        """Current target (mA) for a torque (N·m) on one leg; refuses out-of-range torques."""
        curve = self.legs[leg]
        try:
            return round(curve.current_for(torque_nm))
        except ValueError:
            raise TorqueOutOfRange(
                f"leg {leg}: {torque_nm} N·m is outside the calibrated range "
                f"{curve.min_torque_nm:g}–{curve.max_torque_nm:g} N·m of {self.source}"
            ) from None

    def torque(self, leg: int, current_ma: float) -> float:
        return self.legs[leg].torque(current_ma)

    def check_angle(self, leg: int, angle_deg: float) -> None:
        """Refuse a leg angle outside :attr:`angle_range_deg` (:class:`AngleOutOfRange`)."""
        lo, hi = self.angle_range_deg
        if not (math.isfinite(angle_deg) and lo <= angle_deg <= hi):
            raise AngleOutOfRange(
                f"leg {leg}: angle {angle_deg} deg is outside the range {lo:g}–{hi:g} deg of {self.source}"
            )

    def check_preset(
        self, tau_up_nm: float, tau_down_nm: float, uphill_angle_deg: float | None = None
    ) -> None:
        """Refuse a landing preset any leg could not take, before anything flies.

        Either pair may be any legs (the heading decides), so every leg must reach both
        torques; the uphill angle, when given, must lie in the legs' angle range. Raises
        :class:`TorqueOutOfRange` or :class:`AngleOutOfRange` naming the leg and the range.
        """
        for leg in range(len(self.legs)):
            for tau in (tau_up_nm, tau_down_nm):
                self.current_for(leg, tau)
            if uphill_angle_deg is not None:
                self.check_angle(leg, uphill_angle_deg)

    @property
    def assumed(self) -> bool:
        return self.provenance == "assumed"


def default_calibration_path() -> Path:
    """The curve shipped with the package (provenance: assumed)."""
    return Path(str(resources.files("slopelander.legs") / DEFAULT_FILE))


def load_calibration(path: str | Path | None = None) -> Calibration:
    """Read and check a calibration file; the shipped default if ``path`` is None."""
    path = Path(path) if path is not None else default_calibration_path()
    name = str(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise CalibrationError(name, "(file)", f"cannot read: {exc.strerror}") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise CalibrationError(name, "(file)", f"not valid YAML: {exc}") from None
    return parse_calibration(doc, name)


def _check_units(doc: dict, name: str) -> None:
    """The file says its units, and they are the ones the curves are read in (mA, N*m)."""
    units = doc.get("units")
    if not isinstance(units, dict):
        raise CalibrationError(name, "units", "missing (need current: mA, torque: N*m)")
    if units.get("current") != "mA":
        raise CalibrationError(name, "units.current", "must be mA")
    if units.get("torque") not in TORQUE_UNITS:
        raise CalibrationError(name, "units.torque", "must be N*m")


def _leg_curve(entry: object, where: str, name: str, seen: dict[int, LegCurve]) -> tuple[int, LegCurve]:
    """One leg's entry: a leg index not ``seen`` yet and its curve, current strictly rising and
    torque non-negative, never falling, rising somewhere."""
    if not isinstance(entry, dict):
        raise CalibrationError(name, where, "must be a mapping")
    leg = entry.get("leg")
    if not isinstance(leg, int) or not 0 <= leg < N_LEGS or leg in seen:
        raise CalibrationError(name, f"{where}.leg", f"must be a new index 0..{N_LEGS - 1}")
    current = _numbers(entry.get("current_ma"), name, f"{where}.current_ma")
    torque = _numbers(entry.get("torque_nm"), name, f"{where}.torque_nm")
    if len(current) != len(torque):
        raise CalibrationError(name, f"{where}.torque_nm", "must have as many points as current_ma")
    _check_order(current, name, f"{where}.current_ma", strict=True)
    _check_order(torque, name, f"{where}.torque_nm", strict=False)
    if torque[0] < 0:
        raise CalibrationError(name, f"{where}.torque_nm", "must not be negative")
    if torque[-1] <= torque[0]:
        raise CalibrationError(name, f"{where}.torque_nm", "must rise somewhere")
    return leg, LegCurve(current, torque)


def _angle_range(doc: dict, name: str) -> tuple[float, float]:
    """The leg angles (deg) the curve holds for: the protocol's whole range unless the file narrows it."""
    if "angle_range_deg" not in doc:
        return PROTOCOL_ANGLE_RANGE_DEG
    pair = _numbers(doc["angle_range_deg"], name, "angle_range_deg")
    lo, hi = pair[0], pair[-1]
    if len(pair) != 2 or not (PROTOCOL_ANGLE_RANGE_DEG[0] <= lo < hi <= PROTOCOL_ANGLE_RANGE_DEG[1]):
        raise CalibrationError(
            name, "angle_range_deg", "must be [low, high] with 0 <= low < high <= 37.5 (deg)"
        )
    return lo, hi


def _board_id(doc: dict, name: str) -> str | None:
    """The board the curve was measured on (16 hex digits, lower case), or None when not named."""
    board_id = doc.get("board_id")
    if board_id is None:
        return None
    if not isinstance(board_id, str) or len(board_id) != 16 or not _is_hex(board_id):
        raise CalibrationError(
            name, "board_id", "must be the board's id, 16 hex digits (legs status prints it)"
        )
    return board_id.lower()


def parse_calibration(doc: object, name: str) -> Calibration:
    """Check a loaded document; every problem names the file and the field."""
    if not isinstance(doc, dict):
        raise CalibrationError(name, "(file)", "expected a mapping at the top level")
    provenance = doc.get("provenance")
    if provenance not in PROVENANCES:
        raise CalibrationError(name, "provenance", f"must be one of {', '.join(PROVENANCES)}")
    _check_units(doc, name)
    legs = doc.get("legs")
    if not isinstance(legs, list) or len(legs) != N_LEGS:
        raise CalibrationError(name, "legs", f"must be a list of {N_LEGS} legs")
    curves: dict[int, LegCurve] = {}
    for i, entry in enumerate(legs):
        leg, curve = _leg_curve(entry, f"legs[{i}]", name, curves)
        curves[leg] = curve
    angles = _angle_range(doc, name)
    board_id = _board_id(doc, name)
    return Calibration(tuple(curves[i] for i in range(N_LEGS)), provenance, name, angles, board_id)


def _is_hex(text: str) -> bool:
    try:
        int(text, 16)
    except ValueError:
        return False
    return True


def _numbers(value: object, name: str, field: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) < 2:
        raise CalibrationError(name, field, "must be a list of at least 2 numbers")
    out = []
    for k, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise CalibrationError(name, field, f"point {k} is not a finite number: {v!r}")
        out.append(float(v))
    return tuple(out)


def _check_order(values: Sequence[float], name: str, field: str, strict: bool) -> None:
    for k in range(1, len(values)):
        a, b = values[k - 1], values[k]
        if b < a or (strict and b == a):
            word = "strictly increasing" if strict else "non-decreasing"
            raise CalibrationError(name, field, f"must be {word} (point {k}: {b:g} after {a:g})")
