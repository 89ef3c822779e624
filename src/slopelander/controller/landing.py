"""What the landing will be like, and which leg preset to use for it.

The expected impact speed comes from the descent rate, the cut height and the leg geometry; the
preset comes from the lookup table at (slope, that speed), or the pilot's own preset; either is
refused before the landing if the leg calibration cannot produce its torques.

Geometry (documented assumption): the vehicle descends level over a plane of slope ``s``; the
downward rangefinder at the body centre reads the vertical height ``h`` of the body base above
the ground there. A leg of length ``L`` hinged at ``joint_x`` from the centre, at angle ``a`` from
the vertical, puts its foot ``L cos a`` below the base and ``joint_x + L sin a`` out; the uphill foot
meets ground that is ``(joint_x + L sin a) tan s`` higher. After the cut the vehicle falls freely
from the descent rate over the remaining height ``d = h_cut - L cos a - (joint_x + L sin a) tan s``:
``v = sqrt(v_d^2 + 2 g max(d, 0))``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import yaml

from slopelander.controller.config import RcPreset
from slopelander.controller.table import LookupTable, Preset
from slopelander.errors import SlopelanderError

G = 9.80665


class PresetError(SlopelanderError, ValueError):
    """The chosen preset cannot be set on these legs (outside their calibration)."""


@dataclass(frozen=True)
class LegGeometry:
    """Leg length (m), joint offset from the centre (m) and the leg angle at contact (deg from vertical)."""

    leg_length_m: float
    joint_x_m: float
    leg_angle_deg: float


def model_parameters_path() -> Path:
    """The model's parameter file (read with pyyaml only; the model package is never imported)."""
    return Path(__file__).resolve().parents[1] / "model" / "default_parameters.yaml"


def leg_geometry(path: str | Path | None = None) -> LegGeometry:
    """Leg geometry from the model's parameter file."""
    p = Path(path) if path else model_parameters_path()
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise SlopelanderError(f"{p}: cannot read the leg geometry: {exc}") from None

    def find(key: str) -> float:
        for section in doc.values() if isinstance(doc, dict) else ():
            if isinstance(section, dict) and key in section:
                v = section[key]
                return float(v["value"] if isinstance(v, dict) else v)
        raise SlopelanderError(f"{p}: {key}: missing")

    return LegGeometry(find("leg_length"), find("joint_x"), find("leg_angle_max_deg"))


def expected_impact_speed(descent_mps: float, cut_height_m: float, slope_deg: float,
                          geom: LegGeometry) -> float:
    """Vertical speed (m/s) at first foot contact, per the geometry in the module docstring."""
    for name, v in (("descent rate", descent_mps), ("cut height", cut_height_m), ("slope", slope_deg)):
        if not math.isfinite(v):
            raise ValueError(f"{name} must be a finite number, got {v!r}")
    if not 0 <= slope_deg < 90:
        raise ValueError(f"slope must be within 0..90 deg, got {slope_deg!r}")
    a = math.radians(geom.leg_angle_deg)
    reach = geom.joint_x_m + geom.leg_length_m * math.sin(a)
    d = cut_height_m - geom.leg_length_m * math.cos(a) - reach * math.tan(math.radians(slope_deg))
    return math.sqrt(descent_mps ** 2 + 2 * G * max(d, 0.0))


def choose_preset(slope_deg: float, speed_mps: float, table: LookupTable | None,
                  pilot: RcPreset | None, calibration) -> tuple[float, float, str]:
    """(tau_up, tau_down, where from): the pilot's preset wins, else the table; both checked.

    ``calibration`` is a :class:`slopelander.legs.calibration.Calibration`; every leg must reach
    both torques. Raises :class:`PresetError` (or the table's OutOfTableRange) otherwise.
    """
    if pilot is not None:
        up, down, source = pilot.tau_up_nm, pilot.tau_down_nm, "pilot preset"
    elif table is not None:
        p: Preset = table.lookup(slope_deg, speed_mps)
        if not p.landed:
            raise PresetError(f"the table predicts '{p.outcome}' at {slope_deg:g} deg, "
                              f"{speed_mps:.2f} m/s: no preset lands there")
        up, down, source = p.tau_up, p.tau_down, f"table cell {p.cell} ({p.outcome})"
    else:
        raise PresetError("no lookup table and no pilot preset: nothing to set the legs to")
    for leg in range(len(calibration.legs)):
        for tau in (up, down):
            try:
                calibration.current_for(leg, tau)
            except SlopelanderError as exc:
                raise PresetError(f"{source}: {exc}") from None
    return up, down, source
