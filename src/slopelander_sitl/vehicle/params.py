"""The vehicle's parameter table: the .parm file the real autopilot would be loaded with, plus
the parameters this simulated vehicle reads itself (so PARAM_SET on them changes its behaviour)."""

from __future__ import annotations

import math
from pathlib import Path

# Parameters the simulated vehicle uses, with ArduCopter's names, units and (except the
# rangefinder limits, kept wide so the default vehicle reads its range on the pad) defaults.
VEHICLE_DEFAULTS: dict[str, float] = {
    "MAV_SYSID": 1,
    "SCHED_LOOP_RATE": 400,
    "MOT_PWM_MIN": 1525,
    "MOT_PWM_MAX": 2000,
    "MOT_SPIN_ARM": 0.10,
    "MOT_SPIN_MIN": 0.15,
    "GUID_TIMEOUT": 3.0,
    "LAND_SPEED": 50,  # cm/s
    "WPNAV_SPEED_UP": 250,  # cm/s
    "WPNAV_SPEED_DN": 150,  # cm/s
    "PILOT_SPEED_UP": 250,
    "PILOT_SPEED_DN": 0,
    "ANGLE_MAX": 3000,  # cdeg
    "ATC_SLEW_YAW": 6000,  # cdeg/s: the fastest GUIDED turns to a heading
    "ARMING_CHECK": 1,
    "RC_OPTIONS": 32,  # ArduCopter's default: ARMING_CHECK_THROTTLE (arm with the throttle down)
    "MAV_GCS_SYSID": 255,  # the ground station's system id: RC overrides only from it
    "INS_ACCEL_FILTER": 20,  # Hz
    "INS_GYRO_FILTER": 20,  # Hz
    "RNGFND1_TYPE": 0,
    "RNGFND1_ORIENT": 25,
    "RNGFND1_MIN": 0.05,  # m
    "RNGFND1_MAX": 14.0,  # m
    "WPNAV_RFND_USE": 1,  # GUIDED take-off height over the rangefinder's surface below RNGFND1_MAX
    "DISARM_DELAY": 10,
    "FS_CRASH_CHECK": 1,
    "RTL_ALT": 1500,  # cm
    "SCR_ENABLE": 1,
    "SCR_USER1": 0,  # a parameter ArduPilot keeps for scripts (the tests' fault injection reads it)
    "SIM_OPOS_LAT": 47.3977,  # deg: where home is on the earth (GLOBAL_INT targets), as SITL's --home
    "SIM_OPOS_LNG": 8.5456,  # deg
    "SIM_OPOS_ALT": 400.0,  # m above mean sea level
}


class ParamError(ValueError):
    """A parameter file line or value that cannot be used; names the file and line."""


def load_parm(path: Path) -> dict[str, float]:
    """Read an ArduPilot .parm file (NAME VALUE or NAME,VALUE per line, # comments)."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ParamError(f"{path}: cannot read parameter file: {exc.strerror}") from None
    out: dict[str, float] = {}
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.replace(",", " ").replace("\t", " ").split()
        if len(parts) != 2:
            raise ParamError(f"{path}:{n}: expected 'NAME VALUE', got {raw.strip()!r}")
        name, value = parts
        if len(name) > 16 or not name.replace("_", "").isalnum() or not name[0].isalpha():
            raise ParamError(f"{path}:{n}: {name!r} is not a parameter name (A-Z, 0-9, _, at most 16)")
        try:
            v = float(value)
        except ValueError:
            raise ParamError(f"{path}:{n}: {name} value {value!r} is not a number") from None
        if not math.isfinite(v):
            raise ParamError(f"{path}:{n}: {name} value {value!r} is not finite")
        out[name.upper()] = v
    return out


class Params:
    """Ordered name -> value table with ArduPilot's 16-character names."""

    def __init__(self, initial: dict[str, float] | None = None) -> None:
        self._v: dict[str, float] = dict(VEHICLE_DEFAULTS)
        if initial:
            self._v.update(initial)
        self.names: list[str] = sorted(self._v)

    def __contains__(self, name: str) -> bool:
        return name in self._v

    def __getitem__(self, name: str) -> float:
        return self._v[name]

    def get(self, name: str, default: float | None = None) -> float | None:
        return self._v.get(name, default)

    def set(self, name: str, value: float) -> bool:
        """Set an existing parameter; False for unknown names or non-finite values (as ArduPilot)."""
        if name not in self._v or not math.isfinite(value):
            return False
        self._v[name] = float(value)
        return True

    def index(self, name: str) -> int:
        return self.names.index(name)

    def __len__(self) -> int:
        return len(self.names)
