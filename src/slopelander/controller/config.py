"""The landing controller's settings: one YAML file, every value range-checked by name.

The shipped ``default_config.yaml`` holds every threshold with its unit in the key; a user file
overrides any subset. A bad value never reaches the state machine: :class:`ConfigError` names the
dotted field, what it got and what it expects.
"""

from __future__ import annotations

import copy
import itertools
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from slopelander.errors import SlopelanderError

#: the on-board script's lower bound on the impact threshold (2 g; docs/onboard-script.md), the
#: value of ``script_contract.IMPACT_MIN_MPS2`` (tests/firmware/test_script_contract.py holds them
#: equal; imported by value so that the settings do not depend on the MAVLink modules)
IMPACT_MIN_MPS2 = 2 * 9.80665

#: the uphill foot touches at this range (m) on a 60 deg roof, the shipped table's steepest
#: (controller/landing.py ``contact_range``; tests/controller/test_controller_config.py holds them)
SURVEY_MIN_RANGE_FLOOR_M = 0.55

# field -> (low, high, integer?)  (inclusive bounds)
LIMITS: dict[str, tuple[float, float, bool]] = {
    "link.link_loss_s": (0.2, 30.0, False),
    "link.heartbeat_wait_s": (1.0, 300.0, False),
    # one missed 1 Hz HEARTBEAT is a dropped frame on a noisy radio, not a lost link: at least 2
    "link.heartbeats_missed": (2, 20, True),
    "link.command_timeout_s": (0.05, 5.0, False),
    "link.command_retries": (0, 10, True),
    "link.imu_hz": (1, 200, False),
    "link.range_hz": (1, 200, False),
    "link.min_delivered_fraction": (0.0, 1.0, False),
    "link.poll_period_s": (0.0, 0.05, False),
    "link.position_hz": (1, 200, False),
    "link.attitude_hz": (1, 200, False),
    "link.rc_hz": (1, 50, False),
    "link.servo_hz": (1, 200, False),
    "link.home_alt_hz": (1, 50, False),
    "link.heartbeat_hz": (1, 10, False),
    "descent.rate_mps": (0.1, 3.0, False),
    "descent.resend_hz": (5, 50, False),
    "reflex.cut_height_m": (0.10, 2.00, False),
    "reflex.cut_latency_s": (0.0, 0.5, False),
    "reflex.arm_height_m": (0.2, 20.0, False),
    # at least IMPACT_MIN_MPS2 (2 g), checked below with its reason
    "reflex.impact_threshold_mps2": (0, 200, False),
    "reflex.reverse_thrust_pct": (0, 100, False),
    "reflex.reverse_thrust_ms": (0, 5000, True),
    "reflex.reverse_max_ms": (0, 5000, True),
    "reflex.reverse_still_s": (0.0, 2.0, False),
    "reflex.reverse_ramp_ms": (0, 3000, True),
    "reflex.validity_ms": (100, 10000, True),
    "reflex.refresh_s": (0.05, 5.0, False),
    "reflex.confirm_timeout_s": (0.2, 5.0, False),
    "range.max_age_s": (0.01, 5.0, False),
    "range.min_quality": (0, 100, True),
    # a range moving less than stuck_fraction of the reported descent over stuck_window_s is stuck
    # (controller/stuck_range.py); a window longer than 2 s would outlast most of ARMED's descent
    "range.stuck_window_s": (0.2, 2.0, False),
    "range.stuck_fraction": (0.05, 0.8, False),
    "range.stuck_min_samples": (3, 100, True),
    "legs.tolerance_nm": (0.0, 2.0, False),
    "legs.ready_timeout_s": (0.1, 60.0, False),
    "legs.board_silent_s": (0.05, 10.0, False),
    "legs.angle_tolerance_deg": (0.1, 20.0, False),
    "legs.reconnect_s": (0.1, 60.0, False),
    "settle.still_s": (0.1, 10.0, False),
    "settle.still_mps2": (0.1, 10.0, False),
    "settle.timeout_s": (0.5, 60.0, False),
    "settle.still_speed_mps": (0.005, 1.0, False),
    "settle.slide_speed_mps": (0.01, 5.0, False),
    "settle.slide_m": (0.01, 2.0, False),
    "settle.velocity_max_age_s": (0.01, 5.0, False),
    "takeoff.clear_height_m": (0.2, 10.0, False),
    "takeoff.max_tilt_deg": (1.0, 45.0, False),
    "takeoff.attitude_window_s": (0.01, 1.0, False),
    "takeoff.unknown_slope_deg": (0.0, 80.0, False),
    "rc_presets.channel": (1, 18, True),
    "slope.check_sigmas": (0.0, 10.0, False),
    "slope.pair_window_s": (0.005, 1.0, False),
    "slope.min_points": (5, 10000, True),
    "slope.min_baseline_m": (0.2, 20.0, False),
    "slope.min_side_m": (0.0, 10.0, False),
    "slope.half_span_m": (0.2, 20.0, False),
    "slope.min_inlier_fraction": (0.3, 1.0, False),
    "slope.plane_tolerance_deg": (0.0, 30.0, False),
    "slope.max_sigma_deg": (0.1, 20.0, False),
    "slope.sigma_floor_deg": (0.0, 10.0, False),
    "slope.attitude_error_deg": (0.0, 10.0, False),
    "slope.height_walk_m": (0.0, 1.0, False),
    "slope.survey_length_m": (0.4, 20.0, False),
    # the pass turns back where the range will read ``survey_min_range_m`` once braked, looking
    # ahead a fixed 0.6 s (controller/survey.py): measured for the simulated vehicle at 0.35 m/s,
    # so the pass is flown no faster than twice that
    "slope.survey_speed_mps": (0.05, 0.8, False),
    # at least the range at which the uphill foot touches the steepest roof the shipped table
    # covers (SURVEY_MIN_RANGE_FLOOR_M): a lower turn-back lets the feet meet a rising roof first
    "slope.survey_min_range_m": (SURVEY_MIN_RANGE_FLOOR_M, 3.0, False),
    "slope.survey_timeout_s": (1.0, 600.0, False),
    "slope.max_cross_deg": (0.5, 20.0, False),
    "slope.turn_timeout_s": (1.0, 600.0, False),
}
RC_PRESET_LIMITS = {
    "min_us": (800, 2200),
    "max_us": (800, 2200),
    "tau_up_nm": (0.0, 10.0),
    "tau_down_nm": (0.0, 10.0),
}
#: optional keys of a preset: its name (for the pilot's messages) and the uphill legs' angle (deg
#: below the horizontal, as the table's; null or absent = the preset asks for no angle)
RC_PRESET_OPTIONAL = ("name", "angle_up_deg")
RC_ANGLE_LIMITS = (0.0, 90.0)


class ConfigError(SlopelanderError, ValueError):
    """A setting is missing, unknown or out of range; the message names the field."""

    def __init__(self, source: str, field: str, why: str) -> None:
        super().__init__(f"{source}: {field}: {why}")
        self.field = field


@dataclass(frozen=True)
class RcPreset:
    """One PWM band of the pilot's preset switch and the named preset it selects: torques (N·m)
    and, like the table's, the uphill legs' angle (deg; None = any angle)."""

    min_us: float
    max_us: float
    tau_up_nm: float
    tau_down_nm: float
    name: str = ""
    angle_up_deg: float | None = None


class Config:
    """Validated settings; read with ``cfg['reflex.cut_height_m']`` or ``cfg.reflex['cut_height_m']``."""

    def __init__(self, doc: dict[str, Any], source: str = "config") -> None:
        self.source = source
        self.doc = doc
        self.rc_presets = _validate(doc, source)
        # read in the landing loop's every wake: one dict lookup, not a split and two
        self._flat = {
            f"{s}.{k}": v for s, sec in doc.items() if isinstance(sec, dict) for k, v in sec.items()
        }

    def __getitem__(self, dotted: str) -> Any:
        try:
            return self._flat[dotted]
        except KeyError:
            section, key = dotted.split(".", 1)
            return self.doc[section][key]

    def with_values(self, overrides: dict[str, dict[str, Any]], why: str) -> Config:
        """A copy with ``overrides`` (sections of keys) applied and validated like a user's file;
        ``why`` joins the source, for the errors and records that name it."""
        source = f"{self.source} ({why})"
        return Config(merge(self.doc, overrides, source), source)

    def __getattr__(self, section: str) -> dict[str, Any]:
        try:
            return self.__dict__["doc"][section]
        except KeyError:
            raise AttributeError(section) from None


def default_config_path() -> Path:
    """The shipped defaults."""
    return Path(str(resources.files("slopelander.controller") / "default_config.yaml"))


def _read(path: Path) -> Any:
    try:
        return yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ConfigError(str(path), "(file)", f"cannot read: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(str(path), "(file)", f"not valid YAML: {exc}") from None


def load_config(path: str | Path | None = None) -> Config:
    """The defaults, overridden by the file at ``path`` if given."""
    base = _read(default_config_path())
    if path is None:
        return Config(base, str(default_config_path()))
    user = _read(Path(path))
    if user is None:
        user = {}
    return Config(merge(base, user, str(path)), str(path))


def merge(base: dict[str, Any], user: Any, source: str) -> dict[str, Any]:
    """Override ``base`` with ``user``; unknown sections/keys are errors (typos must not pass)."""
    if not isinstance(user, dict):
        raise ConfigError(source, "(top level)", "expected a mapping of sections")
    out = copy.deepcopy(base)
    for section, values in user.items():
        if section not in base:
            raise ConfigError(source, str(section), f"unknown section (known: {', '.join(base)})")
        if not isinstance(values, dict):
            raise ConfigError(source, str(section), "expected a mapping of settings")
        for key, value in values.items():
            if key not in base[section]:
                raise ConfigError(source, f"{section}.{key}", "unknown setting")
            out[section][key] = value
    return out


def _validate_slope(sl: dict[str, Any], source: str) -> None:
    """The slope section's flag, nullable bound and the relations between its lengths."""
    if not isinstance(sl.get("check_pilot"), bool):
        raise ConfigError(
            source, "slope.check_pilot", f"expected true or false, got {sl.get('check_pilot')!r}"
        )
    b = sl.get("check_bound_deg")
    if b is not None and (
        isinstance(b, bool) or not isinstance(b, (int, float)) or not math.isfinite(b) or not 0.5 <= b <= 45
    ):
        raise ConfigError(source, "slope.check_bound_deg", f"expected null or a number in 0.5..45, got {b!r}")
    if sl["min_baseline_m"] > 2 * sl["half_span_m"]:
        raise ConfigError(
            source, "slope.min_baseline_m", "must not exceed twice slope.half_span_m (no fit could pass)"
        )
    if sl["survey_length_m"] < sl["min_baseline_m"]:
        raise ConfigError(source, "slope.survey_length_m", "must be at least slope.min_baseline_m")
    if 2 * sl["min_side_m"] > sl["survey_length_m"]:
        raise ConfigError(source, "slope.min_side_m", "must be at most half of slope.survey_length_m")


def _check_limits(doc: dict[str, Any], source: str) -> None:
    """Every setting of LIMITS is present, a finite number, whole where it must be, and in range."""
    for field, (lo, hi, integer) in LIMITS.items():
        section, key = field.split(".")
        try:
            v = doc[section][key]
        except (KeyError, TypeError):
            raise ConfigError(source, field, "missing") from None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(source, field, f"expected a number, got {v!r}")
        if integer and v != int(v):
            raise ConfigError(source, field, f"expected a whole number, got {v!r}")
        if not lo <= v <= hi:
            raise ConfigError(source, field, f"{v!r} is outside {lo:g}..{hi:g}")


def _check_reflex_and_settle(doc: dict[str, Any], source: str) -> None:
    """The relations between reflex and settle settings that each range alone cannot hold."""
    reflex, settle = doc["reflex"], doc["settle"]
    if reflex["arm_height_m"] <= reflex["cut_height_m"]:
        raise ConfigError(source, "reflex.arm_height_m", "must be above reflex.cut_height_m")
    if reflex["impact_threshold_mps2"] < IMPACT_MIN_MPS2:
        raise ConfigError(
            source,
            "reflex.impact_threshold_mps2",
            f"{reflex['impact_threshold_mps2']!r} is below {IMPACT_MIN_MPS2:.2f} (2 g): the filtered "
            "accelerometer reads about 1 g at the cut, so a lower threshold fires in the air "
            "(docs/onboard-script.md)",
        )
    if reflex["reverse_max_ms"] < reflex["reverse_thrust_ms"]:
        raise ConfigError(source, "reflex.reverse_max_ms", "must not be below reflex.reverse_thrust_ms")
    if settle["slide_speed_mps"] < settle["still_speed_mps"]:
        raise ConfigError(source, "settle.slide_speed_mps", "must not be below settle.still_speed_mps")
    if reflex["refresh_s"] * 1000 >= reflex["validity_ms"]:
        raise ConfigError(source, "reflex.refresh_s", "must be shorter than reflex.validity_ms")


def _is_number_in(v: object, lo: float, hi: float) -> bool:
    """Whether ``v`` is a number (not a bool) within lo..hi."""
    return not isinstance(v, bool) and isinstance(v, (int, float)) and lo <= v <= hi


def _rc_preset(item: object, i: int, source: str) -> RcPreset:
    """One entry of rc_presets.presets: its keys, PWM band, torques, name and optional angle."""
    name = f"rc_presets.presets[{i}]"
    if (
        not isinstance(item, dict)
        or not set(RC_PRESET_LIMITS) <= set(item)
        or not set(item) <= set(RC_PRESET_LIMITS) | set(RC_PRESET_OPTIONAL)
    ):
        raise ConfigError(
            source,
            name,
            f"expected the keys {', '.join(RC_PRESET_LIMITS)} and optionally {', '.join(RC_PRESET_OPTIONAL)}",
        )
    for k, (lo, hi) in RC_PRESET_LIMITS.items():
        v = item[k]
        if not _is_number_in(v, lo, hi):
            raise ConfigError(source, f"{name}.{k}", f"expected a number in {lo:g}..{hi:g}, got {v!r}")
    if item["min_us"] >= item["max_us"]:
        raise ConfigError(source, f"{name}.min_us", "must be below max_us")
    label = item.get("name", f"preset {i + 1}")
    if not isinstance(label, str) or not label.strip() or len(label) > 20:
        raise ConfigError(source, f"{name}.name", f"expected a name of 1..20 characters, got {label!r}")
    angle = item.get("angle_up_deg")
    lo, hi = RC_ANGLE_LIMITS
    if angle is not None and not _is_number_in(angle, lo, hi):
        raise ConfigError(
            source, f"{name}.angle_up_deg", f"expected null or a number in {lo:g}..{hi:g}, got {angle!r}"
        )
    return RcPreset(
        **{k: float(item[k]) for k in RC_PRESET_LIMITS},
        name=label.strip(),
        angle_up_deg=None if angle is None else float(angle),
    )


def _rc_presets(rc: dict[str, Any], source: str) -> tuple[RcPreset, ...]:
    """The pilot's preset switch: its flag, each preset, and PWM bands that do not overlap."""
    if not isinstance(rc.get("enabled"), bool):
        raise ConfigError(source, "rc_presets.enabled", "expected true or false")
    items = rc.get("presets")
    if not isinstance(items, list):
        raise ConfigError(source, "rc_presets.presets", "expected a list")
    presets = [_rc_preset(item, i, source) for i, item in enumerate(items)]
    if rc["enabled"] and not presets:
        raise ConfigError(source, "rc_presets.presets", "enabled but empty")
    ordered = sorted(presets, key=lambda p: p.min_us)
    for a, b in itertools.pairwise(ordered):
        if b.min_us < a.max_us:
            raise ConfigError(source, "rc_presets.presets", "PWM bands overlap")
    return tuple(presets)


def _validate(doc: Any, source: str) -> tuple[RcPreset, ...]:
    """Check the whole document, section by section; the pilot's presets, read."""
    if not isinstance(doc, dict):
        raise ConfigError(source, "(top level)", "expected a mapping of sections")
    _check_limits(doc, source)
    _check_reflex_and_settle(doc, source)
    _validate_slope(doc["slope"], source)
    return _rc_presets(doc.get("rc_presets", {}), source)
