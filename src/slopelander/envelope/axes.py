"""The two axes of every landing map: surface slope (deg) and vertical impact speed (m/s)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slopelander.errors import SlopelanderError
from slopelander.model import condition_grid


class AxesError(SlopelanderError, ValueError):
    """A map resolution or range that cannot make a grid."""


def _axis(name: str, lo: float, hi: float, step: float) -> np.ndarray:
    if not (np.isfinite(lo) and np.isfinite(hi) and np.isfinite(step)):
        raise AxesError(f"{name}: range and step must be finite numbers")
    if step <= 0:
        raise AxesError(f"{name}: step must be positive, got {step}")
    if hi < lo:
        raise AxesError(f"{name}: maximum {hi} is below minimum {lo}")
    n = int(np.floor((hi - lo) / step + 1e-9)) + 1
    # Rounded so that grid values print and compare exactly (0.1 steps stay 0.7, not 0.70000001).
    return np.round(lo + step * np.arange(n), 9)


@dataclass(frozen=True)
class MapAxes:
    """Slopes (deg) and vertical impact speeds (m/s) of a map, both increasing and uniform."""

    slopes: np.ndarray
    speeds: np.ndarray

    @classmethod
    def build(
        cls,
        slope_step: float = 1.0,
        speed_step: float = 0.1,
        *,
        slope_min: float = 0.0,
        slope_max: float = 60.0,
        speed_min: float = 0.5,
        speed_max: float = 3.0,
    ) -> MapAxes:
        """The paper's range (0-60 deg, 0.5-3 m/s) at a chosen resolution (default 1 deg x 0.1 m/s)."""
        if slope_min < 0 or slope_max > 75:
            raise AxesError("slope: the model covers 0..75 deg")
        if speed_min < 0 or speed_max > 15:
            raise AxesError("speed: the model covers 0..15 m/s")
        return cls(
            _axis("slope", slope_min, slope_max, slope_step), _axis("speed", speed_min, speed_max, speed_step)
        )

    @property
    def shape(self) -> tuple[int, int]:
        return (self.slopes.size, self.speeds.size)

    @property
    def size(self) -> int:
        return self.slopes.size * self.speeds.size

    @property
    def slope_step(self) -> float:
        return round(float(self.slopes[1] - self.slopes[0]), 9) if self.slopes.size > 1 else 1.0

    @property
    def speed_step(self) -> float:
        return round(float(self.speeds[1] - self.speeds[0]), 9) if self.speeds.size > 1 else 0.1

    @property
    def cell_area(self) -> float:
        """Area one cell stands for, deg x m/s."""
        return self.slope_step * self.speed_step

    def conditions(self, **fixed: object) -> np.ndarray:
        """Every (slope, speed) of the map, slope-major, with the other fields as given."""
        return condition_grid(slope_deg=self.slopes, speed=self.speeds, **fixed)

    def to_dict(self) -> dict[str, list[float]]:
        return {"slope_deg": [float(v) for v in self.slopes], "speed": [float(v) for v in self.speeds]}
