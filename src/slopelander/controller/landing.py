"""What the landing will be like, and which leg preset to use for it.

The expected impact speed comes from the descent rate, the cut height and the leg geometry; the
preset comes from the lookup table at (slope, that speed), or the pilot's own preset; either is
refused before the landing if the leg calibration cannot produce its torques.

The impact speed is the vertical speed when the first foot touches, which is what the model (and
so the table) calls the impact speed: the model starts every landing at that first contact.

Geometry: the vehicle descends level over a plane of slope ``s``; the downward rangefinder at the
centre of mass reads the vertical distance from there to the ground below it (a level vehicle's
beam is vertical). A leg of length ``L`` is hinged ``joint_x`` out from and ``joint_z`` below the
centre of mass, at angle ``q`` below the horizontal (the model's convention: 37.5 deg fully
extended, less when compressed). Its foot is ``joint_z + L sin q`` below and ``joint_x + L cos q``
out; the uphill foot meets ground that is ``(joint_x + L cos q) tan s`` higher, so it touches when
the range reads ``h_c = joint_z + L sin q + (joint_x + L cos q) tan s``. The uphill leg's angle is
the preset's when the preset sets one.

Dynamics: the script stops the motors when the range reads ``h_cut``; the vehicle keeps the descent
rate ``v_d`` for the cut latency ``t_l`` (range period, script cycle, output), then the thrust decays
with the rotors, ``T = m g exp(-t / tau_T)`` with ``tau_T`` half the rotor speed time constant
(thrust goes with speed squared). The height fallen is integrated until it reaches
``d = h_cut - h_c``; when ``d <= 0`` the uphill foot touches *before* the cut, at ``v_d``. Without the
latency and the decay this is the free fall ``v = sqrt(v_d^2 + 2 g d)``.

Why the first version was wrong (2026-11-23): it measured the leg angle from the vertical (the
model measures it from the horizontal), left out ``joint_z`` and the motors' stopping, and the demo
took the fastest descent after the cut as the measured impact. In the simulated 35 deg demo the
uphill foot touches at a range of about 0.28 m, just below the 0.30 m cut, at ~0.55 m/s (first
IMU spike); the clamped uphill leg then yields and the vehicle pivots onto its downhill foot, which
lands at ~1.45-1.55 m/s: part of the landing the model simulates from the first contact.
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
    leg_angle_deg: float  # below the horizontal, as in the model
    joint_z_m: float = 0.0


@dataclass(frozen=True)
class CutDynamics:
    """How the motors stop: latency from the range reading to the outputs (s), and the thrust's
    decay time constant after it (s)."""

    latency_s: float = 0.0
    thrust_tau_s: float = 0.0


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

    return LegGeometry(find("leg_length"), find("joint_x"), find("leg_angle_max_deg"), find("joint_z"))


def cut_dynamics(latency_s: float, path: str | Path | None = None) -> CutDynamics:
    """The cut latency (from the settings) and the thrust decay from the model's rotor time constant."""
    p = Path(path) if path else model_parameters_path()
    try:
        doc = yaml.safe_load(p.read_text())
        tau = float(doc["parameters"]["rotor_time_constant"]["value"])
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise SlopelanderError(f"{p}: cannot read rotor_time_constant: {exc}") from None
    return CutDynamics(latency_s, tau / 2.0)


def contact_range(slope_deg: float, geom: LegGeometry, uphill_angle_deg: float | None = None) -> float:
    """The range reading (m) at which the uphill foot touches, per the module docstring."""
    q = math.radians(geom.leg_angle_deg if uphill_angle_deg is None else uphill_angle_deg)
    reach = geom.joint_x_m + geom.leg_length_m * math.cos(q)
    drop = geom.joint_z_m + geom.leg_length_m * math.sin(q)
    return drop + reach * math.tan(math.radians(slope_deg))


#: the cut's longest latency (s): the range crossing the cut height is seen up to one 20 Hz
#: sample late and confirmed by the next (docs/onboard-script.md, ``reflex.cut_latency_s``)
CUT_LATENCY_MAX_S = 0.10
#: the clearance (m) kept between the motors' stop and the uphill foot's touch, beyond that fall
FOOT_MARGIN_M = 0.02


def landing_cut_height(
    cut_height_m: float,
    descent_mps: float,
    slope_deg: float,
    geom: LegGeometry,
    uphill_angle_deg: float | None,
) -> float:
    """The cut height (m) for one landing: the configured one, raised where the uphill foot would
    meet the roof before the motors stop. Above about 30 deg the uphill foot touches at a range of
    more than 0.30 m less the cut's fall (0.34 m at 45 deg with the table's uphill angle): cut
    there, the motors pushed the foot into the roof and the cut followed the contact (soak on
    ArduCopter, 0750e6b, landing 79). Raised to the contact range plus the descent over the cut's
    longest latency and :data:`FOOT_MARGIN_M`."""
    need = contact_range(slope_deg, geom, uphill_angle_deg) + descent_mps * CUT_LATENCY_MAX_S + FOOT_MARGIN_M
    return max(cut_height_m, round(need, 3))


def _fall(v0: float, t: float, cut: CutDynamics) -> tuple[float, float]:
    """(height fallen, speed) ``t`` s after the cut decision, per the module docstring."""
    if t <= cut.latency_s:
        return v0 * t, v0
    u, tau = t - cut.latency_s, cut.thrust_tau_s
    decay = tau * (1.0 - math.exp(-u / tau)) if tau > 0 else 0.0
    speed = v0 + G * (u - decay)
    fallen = v0 * t + G * (u * u / 2.0 - tau * u + tau * decay)
    return fallen, speed


def expected_impact_speed(
    descent_mps: float,
    cut_height_m: float,
    slope_deg: float,
    geom: LegGeometry,
    uphill_angle_deg: float | None = None,
    cut: CutDynamics | None = None,
) -> float:
    """Vertical speed (m/s) at first foot contact, per the module docstring (``cut`` None: the
    motors stop at once)."""
    for name, v in (("descent rate", descent_mps), ("cut height", cut_height_m), ("slope", slope_deg)):
        if not math.isfinite(v):
            raise ValueError(f"{name} must be a finite number, got {v!r}")
    if not 0 <= slope_deg < 90:
        raise ValueError(f"slope must be within 0..90 deg, got {slope_deg!r}")
    d = cut_height_m - contact_range(slope_deg, geom, uphill_angle_deg)
    if d <= 0:
        return descent_mps
    if cut is None or (cut.latency_s <= 0 and cut.thrust_tau_s <= 0):
        return math.sqrt(descent_mps**2 + 2 * G * d)
    lo, hi = 0.0, 0.01
    while _fall(descent_mps, hi, cut)[0] < d:
        hi *= 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _fall(descent_mps, mid, cut)[0] < d else (lo, mid)
    return _fall(descent_mps, hi, cut)[1]


@dataclass(frozen=True)
class LegPreset:
    """The legs for one landing: torques per real joint (N·m), the uphill rest angle (deg below
    the horizontal; None when the source does not ask for one) and where they came from."""

    tau_up: float
    tau_down: float
    angle_up_deg: float | None
    source: str


def choose_preset(
    slope_deg: float, speed_mps: float, table: LookupTable | None, pilot: RcPreset | None, calibration
) -> tuple[float, float, str]:
    """(tau_up, tau_down, where from): :func:`choose_leg_preset` without the angle."""
    p = choose_leg_preset(slope_deg, speed_mps, table, pilot, calibration)
    return p.tau_up, p.tau_down, p.source


def choose_leg_preset(
    slope_deg: float, speed_mps: float, table: LookupTable | None, pilot: RcPreset | None, calibration
) -> LegPreset:
    """The pilot's preset wins, else the table's cell; either is checked before the flight.

    ``calibration`` is a :class:`slopelander.legs.calibration.Calibration`; every leg must reach
    both torques and the angle. Raises :class:`PresetError` (or the table's OutOfTableRange).
    """
    angle: float | None = None
    if pilot is not None:
        up, down = pilot.tau_up_nm, pilot.tau_down_nm
        source = f"pilot preset '{pilot.name}'" if pilot.name else "pilot preset"
        angle = pilot.angle_up_deg
    elif table is not None:
        p: Preset = table.lookup(slope_deg, speed_mps)
        if not p.landed:
            raise PresetError(
                f"the table predicts '{p.outcome}' at {slope_deg:g} deg, "
                f"{speed_mps:.2f} m/s: no preset lands there"
            )
        up, down, source = p.tau_up, p.tau_down, f"table cell {p.cell} ({p.outcome})"
        angle = p.angle_up_deg
    else:
        raise PresetError("no lookup table and no pilot preset: nothing to set the legs to")
    try:
        calibration.check_preset(up, down, angle)
    except SlopelanderError as exc:
        raise PresetError(f"{source}: {exc}") from None
    return LegPreset(up, down, angle, source)


def plan_landing(
    descent_mps: float,
    cut_height_m: float,
    slope_deg: float,
    geom: LegGeometry,
    table: LookupTable | None,
    pilot: RcPreset | None,
    calibration,
    cut: CutDynamics | None = None,
) -> tuple[LegPreset, float]:
    """The preset and the impact speed it was chosen for, from the landing's cut height
    (:func:`landing_cut_height`).

    The table's uphill angle changes where the uphill foot touches, so the speed is computed
    again with that angle and the cell looked up again (the angle varies with the slope only,
    so the second lookup settles it).
    """
    h = landing_cut_height(cut_height_m, descent_mps, slope_deg, geom, None)
    speed = expected_impact_speed(descent_mps, h, slope_deg, geom, None, cut)
    preset = choose_leg_preset(slope_deg, speed, table, pilot, calibration)
    if preset.angle_up_deg is not None:
        h = landing_cut_height(cut_height_m, descent_mps, slope_deg, geom, preset.angle_up_deg)
        speed = expected_impact_speed(descent_mps, h, slope_deg, geom, preset.angle_up_deg, cut)
        preset = choose_leg_preset(slope_deg, speed, table, pilot, calibration)
    return preset, speed


def angle_instruction(angle_up_deg: float | None, board_can_set: bool) -> str | None:
    """What the pilot must do by hand before the flight, or None (no angle, or the board sets it)."""
    if angle_up_deg is None or board_can_set:
        return None
    return (
        f"this leg board cannot set leg angles: set the uphill legs to {angle_up_deg:.1f} deg "
        "below the horizontal by hand before the flight (the landing is refused otherwise)"
    )
