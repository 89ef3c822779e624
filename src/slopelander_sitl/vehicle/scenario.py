"""Scenario file (YAML): the world, wind, the pilot's RC inputs over time and sensor faults, all
deterministic from the seed. See docs/simulated-vehicle.md for the format."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from slopelander.model.landing import Model
from slopelander_sitl.vehicle.sensors import NormalStream, Range
from slopelander_sitl.vehicle.wind import Wind, wind_from_dict

RANGE_FAULTS = ("rangefinder_dropout", "rangefinder_spike", "rangefinder_stuck", "rangefinder_noise")
IMU_FAULTS = ("imu_noise", "imu_spike")
#: the on-board script not run (late or not answering: the scheduler skips it; its overrides lapse)
SCRIPT_FAULTS = ("script_stall",)
FAULT_KINDS = RANGE_FAULTS + IMU_FAULTS + SCRIPT_FAULTS
TOP_KEYS = {
    "seed",
    "start_on",
    "slope_deg",
    "roof_x",
    "roof_z",
    "start_x",
    "noise",
    "rc",
    "faults",
    "model_params",
    "wind",
    "ridge",
    "roof_length",
    "rangefinder",
    "fall_azimuth_deg",
}
RIDGES = ("step", "gable")
BEAM_RETURNS = ("mean", "nearest")
DEFAULT_RC = {1: 1500, 2: 1500, 3: 1000, 4: 1500}


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message names the file and the field."""


@dataclass(frozen=True)
class Fault:
    kind: str
    start: float
    end: float
    value: float
    #: a rangefinder fault acts only while the sensor's true reading is at or below this (m): a
    #: sensor that loses its returns near the roof, at a height a flight test can name
    below_m: float = math.inf


@dataclass
class Scenario:
    seed: int = 0
    slope_deg: float = 20.0
    #: where the roof's plane falls (deg from north, clockwise): 0 away from the pad, 90 east
    fall_azimuth_deg: float = 0.0
    roof_x: float = 3.0
    roof_z: float = 0.5
    start_x: float = 0.0  # m, world x; on the roof: beyond roof_x
    start_on: str = "pad"  # or "roof"
    ridge: str = "step"  # the roof's top edge: a step up from the pad, or a gable ridge
    roof_length: float = 1e4  # m along x from the top edge to the gutter (beyond: nothing in range)
    beam_width_deg: float = 2.0  # the rangefinder's full beam width
    beam_return: str = "mean"  # mean (a lidar's centroid) | nearest (a sonar's first echo)
    edge_dropout_m: float = 0.1  # neighbouring rays further apart than this: no return
    accel_noise: float = 0.05  # m/s^2, 1 sigma per sample
    gyro_noise: float = 0.002  # rad/s
    range_noise: float = 0.005  # m
    rc: list[tuple[float, dict[int, int]]] = field(default_factory=list)
    faults: list[Fault] = field(default_factory=list)
    model_params: dict[str, float] = field(default_factory=dict)
    wind: Wind = field(default_factory=Wind)
    _stuck: float | None = None

    def model(self) -> Model:
        return Model.default().with_params(**self.model_params) if self.model_params else Model.default()

    def rc_at(self, chan: int, t: float) -> int:
        value = DEFAULT_RC.get(chan, 1500)
        for t0, chans in self.rc:
            if t0 > t:
                break
            value = chans.get(chan, value)
        return value

    def apply_events(self, vehicle: object) -> None:
        """Hook for timed events that act on the vehicle itself (none yet besides RC and faults)."""

    def _active(self, t: float, kinds: tuple[str, ...]) -> list[Fault]:
        return [f for f in self.faults if f.kind in kinds and f.start <= t < f.end]

    # The checks below run for every physics step; most scenarios have no faults, and then each
    # returns at once what the general path gives for no active fault.

    def script_stalled(self, t: float) -> bool:
        """Whether the on-board script is not run at vehicle time ``t``."""
        return bool(self.faults) and bool(self._active(t, SCRIPT_FAULTS))

    def imu_spike(self, t: float) -> float:
        if not self.faults:
            return 0  # sum() of nothing, as below
        return sum(f.value for f in self._active(t, ("imu_spike",)))

    def imu_extra_noise(self, t: float) -> float:
        if not self.faults:
            return 0
        return sum(f.value for f in self._active(t, ("imu_noise",)))

    def range_fault(self, t: float, r: Range, rng: np.random.Generator | NormalStream) -> Range:
        """The reading ``r`` with the range noise (one draw from ``rng`` when the distance is
        finite) and the faults active at ``t``."""
        d = r.distance_m + self.range_noise * rng.normal() if math.isfinite(r.distance_m) else r.distance_m
        r = Range(d, r.status, r.quality_pct)
        if not self.faults:
            self._stuck = None
            return r
        active = [f for f in self._active(t, RANGE_FAULTS) if not r.distance_m > f.below_m]
        if not any(f.kind == "rangefinder_stuck" for f in active):
            self._stuck = None
        for f in active:
            if f.kind == "rangefinder_dropout":
                return Range(0.0, 1, 0)  # NoData
            if f.kind == "rangefinder_stuck":
                if self._stuck is None:
                    self._stuck = r.distance_m
                r = Range(self._stuck, r.status, r.quality_pct)
            elif f.kind == "rangefinder_spike":
                r = Range(f.value, r.status, r.quality_pct)
            elif f.kind == "rangefinder_noise":
                r = Range(r.distance_m + f.value * rng.normal(), r.status, r.quality_pct)
        return r


def _num(src: str, name: str, v: object, lo: float, hi: float) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise ScenarioError(f"{src}: {name} must be a number, got {v!r}")
    if not lo <= float(v) <= hi:
        raise ScenarioError(f"{src}: {name} = {v} must lie within {lo}..{hi}")
    return float(v)


def load_scenario(path: Path | None) -> Scenario:
    if path is None:
        return Scenario()
    src = str(path)
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise ScenarioError(f"{src}: cannot read: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{src}: not valid YAML: {exc}") from None
    return scenario_from_dict(data or {}, src)


def _read_seed(s: Scenario, data: dict, src: str) -> None:
    """The seed every random draw of the run comes from: a non-negative integer."""
    if "seed" in data:
        if not isinstance(data["seed"], int) or isinstance(data["seed"], bool) or data["seed"] < 0:
            raise ScenarioError(f"{src}: seed must be a non-negative integer, got {data['seed']!r}")
        s.seed = data["seed"]


def _read_world(s: Scenario, data: dict, src: str) -> None:
    """The roof (slope, edge, height, ridge, length, fall direction) and where the vehicle starts."""
    s.slope_deg = _num(src, "slope_deg", data.get("slope_deg", s.slope_deg), 0.0, 60.0)
    s.roof_x = _num(src, "roof_x", data.get("roof_x", s.roof_x), 0.5, 1000.0)
    s.roof_z = _num(src, "roof_z", data.get("roof_z", s.roof_z), -10.0, 100.0)
    s.start_on = data.get("start_on", "pad")
    if s.start_on not in ("pad", "roof"):
        raise ScenarioError(f"{src}: start_on must be 'pad' or 'roof', got {s.start_on!r}")
    if s.start_on == "pad":
        s.start_x = _num(src, "start_x", data.get("start_x", s.start_x), -1000.0, s.roof_x - 0.5)
    else:
        s.start_x = _num(src, "start_x", data.get("start_x", s.roof_x + 1.0), s.roof_x + 0.5, 1e4)
    s.ridge = data.get("ridge", s.ridge)
    if s.ridge not in RIDGES:
        raise ScenarioError(f"{src}: ridge must be one of {', '.join(RIDGES)}, got {s.ridge!r}")
    s.roof_length = _num(src, "roof_length", data.get("roof_length", s.roof_length), 0.5, 1e4)
    s.fall_azimuth_deg = (
        _num(src, "fall_azimuth_deg", data.get("fall_azimuth_deg", s.fall_azimuth_deg), -360.0, 360.0) % 360.0
    )
    if s.ridge == "gable" and s.fall_azimuth_deg != 0.0:
        raise ScenarioError(
            f"{src}: ridge 'gable' needs a roof falling north (fall_azimuth_deg 0), "
            f"got fall_azimuth_deg {data['fall_azimuth_deg']!r}"
        )


def _read_rangefinder(s: Scenario, data: dict, src: str) -> None:
    """The rangefinder's beam: its width, which return it reports, and where edges drop it out."""
    beam = data.get("rangefinder", {})
    if not isinstance(beam, dict) or set(beam) - {"beam_deg", "return", "edge_dropout_m"}:
        raise ScenarioError(f"{src}: rangefinder must be a mapping with beam_deg, return, edge_dropout_m")
    s.beam_width_deg = _num(src, "rangefinder.beam_deg", beam.get("beam_deg", s.beam_width_deg), 0.0, 60.0)
    s.beam_return = beam.get("return", s.beam_return)
    if s.beam_return not in BEAM_RETURNS:
        raise ScenarioError(
            f"{src}: rangefinder.return must be one of {', '.join(BEAM_RETURNS)}, got {s.beam_return!r}"
        )
    s.edge_dropout_m = _num(
        src, "rangefinder.edge_dropout_m", beam.get("edge_dropout_m", s.edge_dropout_m), 0.001, 100.0
    )


def _read_noise(s: Scenario, data: dict, src: str) -> None:
    """The sensors' 1-sigma noise (SI): accelerometer, gyro, range."""
    noise = data.get("noise", {})
    if not isinstance(noise, dict) or set(noise) - {"accel", "gyro", "range"}:
        raise ScenarioError(f"{src}: noise must be a mapping with accel, gyro, range (1-sigma, SI)")
    s.accel_noise = _num(src, "noise.accel", noise.get("accel", s.accel_noise), 0.0, 50.0)
    s.gyro_noise = _num(src, "noise.gyro", noise.get("gyro", s.gyro_noise), 0.0, 10.0)
    s.range_noise = _num(src, "noise.range", noise.get("range", s.range_noise), 0.0, 5.0)


def _rc_event(ev: object, where: str, src: str, last: float) -> tuple[float, dict[int, int]]:
    """One change of the pilot's sticks: its time (s, not before the ``last`` one's) and the new
    PWM of each channel named."""
    if not isinstance(ev, dict) or set(ev) != {"t", "channels"} or not isinstance(ev["channels"], dict):
        raise ScenarioError(f"{src}: {where} must be {{t: s, channels: {{1: pwm, ...}}}}")
    t = _num(src, f"{where}.t", ev["t"], 0.0, 1e6)
    if t < last:
        raise ScenarioError(f"{src}: {where}.t = {t} goes back in time")
    chans = {}
    for ch, pwm in ev["channels"].items():
        if not isinstance(ch, int) or not 1 <= ch <= 16:
            raise ScenarioError(f"{src}: {where}.channels: channel {ch!r} must be 1..16")
        chans[ch] = int(_num(src, f"{where}.channels.{ch}", pwm, 800, 2200))
    return t, chans


def _read_rc(s: Scenario, data: dict, src: str) -> None:
    """The pilot's RC inputs over time, in time order."""
    rc = data.get("rc", [])
    if not isinstance(rc, list):
        raise ScenarioError(f"{src}: rc must be a list of {{t: s, channels: {{1: pwm, ...}}}}")
    last = -1.0
    for i, ev in enumerate(rc):
        t, chans = _rc_event(ev, f"rc[{i}]", src, last)
        last = t
        s.rc.append((t, chans))


def _fault(f: object, where: str, src: str) -> Fault:
    """One sensor or script fault: its kind, when it starts and ends (s), and its value."""
    if (
        not isinstance(f, dict)
        or not {"kind", "start", "end"} <= set(f)
        or set(f) - {"kind", "start", "end", "value", "below_m"}
    ):
        raise ScenarioError(f"{src}: {where} needs kind, start, end (s) and optionally value, below_m")
    if f["kind"] not in FAULT_KINDS:
        raise ScenarioError(f"{src}: {where}.kind {f['kind']!r} unknown; one of {FAULT_KINDS}")
    start = _num(src, f"{where}.start", f["start"], 0.0, 1e6)
    end = _num(src, f"{where}.end", f["end"], start, 1e6)
    value = _num(src, f"{where}.value", f.get("value", 0.0), -1e4, 1e4)
    if "below_m" in f and f["kind"] not in RANGE_FAULTS:
        raise ScenarioError(f"{src}: {where}.below_m applies to rangefinder faults only")
    below = _num(src, f"{where}.below_m", f["below_m"], 0.0, 100.0) if "below_m" in f else math.inf
    return Fault(f["kind"], start, end, value, below)


def _read_faults(s: Scenario, data: dict, src: str) -> None:
    """The faults list, each one checked."""
    faults = data.get("faults", [])
    if not isinstance(faults, list):
        raise ScenarioError(f"{src}: faults must be a list")
    for i, f in enumerate(faults):
        s.faults.append(_fault(f, f"faults[{i}]", src))


def _read_model_params(s: Scenario, data: dict, src: str) -> None:
    """Model parameters over the defaults, checked by building the model with them."""
    mp = data.get("model_params", {})
    if not isinstance(mp, dict):
        raise ScenarioError(f"{src}: model_params must be a mapping of model parameter names to values")
    for name, v in mp.items():
        s.model_params[str(name)] = _num(src, f"model_params.{name}", v, -1e9, 1e9)
    try:
        s.model()
    except Exception as exc:  # the model's own validation names the parameter
        raise ScenarioError(f"{src}: model_params: {exc}") from None


def scenario_from_dict(data: object, src: str = "scenario") -> Scenario:
    """A scenario from its parsed YAML, checked section by section; errors name ``src`` and the field."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{src}: the top level must be a mapping")
    unknown = set(data) - TOP_KEYS
    if unknown:
        raise ScenarioError(f"{src}: unknown field(s) {sorted(unknown)}; known: {sorted(TOP_KEYS)}")
    s = Scenario()
    _read_seed(s, data, src)
    _read_world(s, data, src)
    _read_rangefinder(s, data, src)
    _read_noise(s, data, src)
    _read_rc(s, data, src)
    _read_faults(s, data, src)
    if "wind" in data:
        s.wind = wind_from_dict(
            data["wind"],
            s.seed,
            lambda name, v, lo, hi: _num(src, name, v, lo, hi),
            lambda msg: ScenarioError(f"{src}: {msg}"),
        )
    _read_model_params(s, data, src)
    return s
