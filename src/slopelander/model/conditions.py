"""Landing conditions: what the world and the pilot's presets look like at impact.

Torques are per *real* joint (what the leg board sets and the paper quotes); the model
doubles them for a planar leg, which stands for a pair (see ``docs/model.md``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np

from slopelander.errors import SlopelanderError

MAX_REVERSE_DURATION = 30.0  # s: longer than any landing's horizon
MAX_REVERSE_RAMP = 10.0  # s


class ConditionError(SlopelanderError, ValueError):
    """A landing condition is outside what the model can represent."""

    def __init__(self, field: str, value: object, why: str) -> None:
        super().__init__(f"landing condition '{field}' = {value!r}: {why}")
        self.field = field
        self.value = value


@dataclass(frozen=True)
class LandingConditions:
    """One landing: the slope, the impact state and the leg presets.

    Sign conventions: x points downhill along the horizontal, z up; pitch is positive
    nose-up in the x-z plane (counter-clockwise), so tipping over the downhill legs is
    negative pitch, as in the paper's flip criterion (pitch < -80 deg).
    """

    slope_deg: float = 0.0
    speed: float = 2.0
    """Vertical impact speed, m/s, positive downward."""
    horizontal_speed: float = 0.0
    """Horizontal speed at impact, m/s, positive toward +x (downhill for a positive slope)."""
    pitch_deg: float = 0.0
    pitch_rate_dps: float = 0.0
    tau_up: float = 1.7
    """Friction torque of each uphill joint, N*m (per real joint)."""
    tau_down: float = 1.7
    """Friction torque of each downhill joint, N*m (per real joint)."""
    angle_up_deg: float = 37.5
    angle_down_deg: float = 37.5
    reverse_percent: float = 0.0
    """Reverse rotor command from impact, percent of the full reverse command (a rotor speed:
    thrust goes with its square, so 70 % gives 49 % of full reverse thrust); 0 = rotors stay off."""
    reverse_delay: float = 0.0
    """Seconds between impact and the reverse-thrust command (detection latency)."""
    reverse_duration: float = math.inf
    """Seconds the full reverse command is held from that command before it ends; ``inf`` (the
    default, and what the maps assume) holds it to the end of the horizon."""
    reverse_ramp: float = 0.0
    """Seconds over which the command then falls linearly to zero; 0 = a step (the on-board
    script's ramp, ``reflex.reverse_ramp_ms``). Needs a finite ``reverse_duration``."""

    @property
    def thrust_ends(self) -> bool:
        """True if the rotors are commanded to zero again within the landing."""
        return self.reverse_percent > 0.0 and math.isfinite(self.reverse_duration)

    @property
    def thrust_off_time(self) -> float:
        """Seconds after first contact at which the reverse command has reached zero for good;
        0 when there is no thrust that ends (none, or held): the landing is judged from there."""
        if not self.thrust_ends:
            return 0.0
        return self.reverse_delay + self.reverse_duration + self.reverse_ramp

    def validate(self, angle_min_deg: float = 0.0, angle_max_deg: float = 37.5) -> None:
        """Raise :class:`ConditionError` naming the first field that makes no sense."""
        for f in fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or math.isnan(v):
                raise ConditionError(f.name, v, "must be a number")
            if f.name != "reverse_duration" and not math.isfinite(v):
                raise ConditionError(f.name, v, "must be a finite number")
        if not -75.0 <= self.slope_deg <= 75.0:
            raise ConditionError("slope_deg", self.slope_deg, "must lie within -75..75 deg")
        if not 0.0 <= self.speed <= 15.0:
            raise ConditionError("speed", self.speed, "must lie within 0..15 m/s (downward)")
        if abs(self.horizontal_speed) > 15.0:
            raise ConditionError("horizontal_speed", self.horizontal_speed, "beyond 15 m/s")
        if abs(self.pitch_deg) > 60.0:
            raise ConditionError("pitch_deg", self.pitch_deg, "beyond +-60 deg at impact")
        if abs(self.pitch_rate_dps) > 720.0:
            raise ConditionError("pitch_rate_dps", self.pitch_rate_dps, "beyond +-720 deg/s")
        for name in ("tau_up", "tau_down"):
            if not 0.0 <= getattr(self, name) <= 10.0:
                raise ConditionError(name, getattr(self, name), "must lie within 0..10 N*m")
        for name in ("angle_up_deg", "angle_down_deg"):
            v = getattr(self, name)
            if not angle_min_deg <= v <= angle_max_deg:
                raise ConditionError(
                    name, v, f"must lie within the joint's range {angle_min_deg}..{angle_max_deg} deg"
                )
        if not 0.0 <= self.reverse_percent <= 100.0:
            raise ConditionError("reverse_percent", self.reverse_percent, "must lie within 0..100")
        if not 0.0 <= self.reverse_delay <= 5.0:
            raise ConditionError("reverse_delay", self.reverse_delay, "must lie within 0..5 s")
        d = self.reverse_duration
        if not (0.0 < d <= MAX_REVERSE_DURATION or d == math.inf):
            raise ConditionError(
                "reverse_duration",
                d,
                f"must lie within 0..{MAX_REVERSE_DURATION:g} s (above 0: a thrust held 0 s is "
                "reverse_percent 0), or be inf (held to the horizon)",
            )
        if not 0.0 <= self.reverse_ramp <= MAX_REVERSE_RAMP:
            raise ConditionError(
                "reverse_ramp", self.reverse_ramp, f"must lie within 0..{MAX_REVERSE_RAMP:g} s"
            )
        if self.reverse_ramp > 0.0 and d == math.inf:
            raise ConditionError(
                "reverse_ramp", self.reverse_ramp, "a ramp needs a finite reverse_duration to end from"
            )

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    def as_file_dict(self) -> dict[str, float]:
        """The fields for a file: a thrust held to the horizon leaves its end out, so that JSON
        holds no ``Infinity`` and files read as before the thrust could end."""
        d = asdict(self)
        if not math.isfinite(self.reverse_duration):
            del d["reverse_duration"], d["reverse_ramp"]
        return d


CONDITION_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(LandingConditions))
CONDITION_DTYPE = np.dtype([(name, np.float64) for name in CONDITION_FIELDS])
_DURATION_COLUMN = CONDITION_FIELDS.index("reverse_duration")


def reverse_text(percent: float) -> str:
    """The reverse command as a user should read it: a rotor speed, and the thrust it gives (its
    square), so that 70 % is not taken for 70 % of the thrust."""
    return f"reverse command {percent:g} % ({percent**2 / 100:.3g} % of full reverse thrust)"


def default_conditions(n: int) -> np.ndarray:
    """``n`` rows of :data:`CONDITION_DTYPE` holding the defaults (a zero-filled array would
    say a reverse thrust held for 0 s, which the model refuses)."""
    out = np.empty(n, dtype=CONDITION_DTYPE)
    for name, value in asdict(LandingConditions()).items():
        out[name] = value
    return out


def conditions_array(conditions: list[LandingConditions] | np.ndarray) -> np.ndarray:
    """Pack conditions into a structured array (the batch path's input), validating each."""
    if isinstance(conditions, np.ndarray):
        missing = [n for n in CONDITION_FIELDS if n not in (conditions.dtype.names or ())]
        if missing:
            raise ConditionError(missing[0], None, "missing from the conditions array")
        out = np.empty(conditions.shape[0], dtype=CONDITION_DTYPE)
        for n in CONDITION_FIELDS:
            out[n] = conditions[n]
        flat = out.view((np.float64, len(CONDITION_FIELDS)))
        # every column finite, but for the held thrust's +inf duration
        ok = np.isfinite(flat) | ((flat == np.inf) & (np.arange(flat.shape[1]) == _DURATION_COLUMN))
        bad = ~ok.all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ConditionError("row", i, "contains a non-finite value")
        return out
    out = np.empty(len(conditions), dtype=CONDITION_DTYPE)
    for i, c in enumerate(conditions):
        out[i] = tuple(getattr(c, n) for n in CONDITION_FIELDS)
    return out


def condition_grid(**axes: object) -> np.ndarray:
    """Cartesian product of condition values, e.g. ``condition_grid(slope_deg=range(0, 61),
    speed=np.arange(0.5, 3.01, 0.1), tau_up=1.7)``; unnamed fields take their defaults."""
    defaults = LandingConditions()
    names = list(axes)
    for n in names:
        if n not in CONDITION_FIELDS:
            raise ConditionError(n, axes[n], f"unknown condition; known: {', '.join(CONDITION_FIELDS)}")
    values = [np.atleast_1d(np.asarray(axes[n], dtype=np.float64)) for n in names]
    mesh = np.meshgrid(*values, indexing="ij") if values else []
    size = int(np.prod([v.size for v in values])) if values else 1
    out = np.empty(size, dtype=CONDITION_DTYPE)
    for n in CONDITION_FIELDS:
        out[n] = getattr(defaults, n)
    for n, m in zip(names, mesh, strict=True):
        out[n] = m.ravel()
    return out
