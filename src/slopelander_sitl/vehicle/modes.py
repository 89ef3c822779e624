"""ArduCopter flight-mode numbers (custom_mode) this vehicle flies, and their names."""

from __future__ import annotations

STABILIZE = 0
ALT_HOLD = 2
GUIDED = 4
LOITER = 5
RTL = 6
LAND = 9
BRAKE = 17

NAMES = {
    STABILIZE: "STABILIZE",
    ALT_HOLD: "ALT_HOLD",
    GUIDED: "GUIDED",
    LOITER: "LOITER",
    RTL: "RTL",
    LAND: "LAND",
    BRAKE: "BRAKE",
}

# Modes that hold a position or velocity target (the rest take pilot sticks).
POSITION_MODES = {GUIDED, LOITER, RTL, LAND, BRAKE}
# Modes ArduCopter lets you arm in (Mode::allows_arming; GUIDED only from a GCS or a script).
ARMABLE = {STABILIZE, ALT_HOLD, GUIDED, LOITER}
# Modes whose throttle is the pilot's stick (Mode::has_manual_throttle).
MANUAL_THROTTLE = {STABILIZE}
