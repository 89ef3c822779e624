"""What every state has: a name, enter (may refuse), step (may move on), leave."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

from slopelander.controller import script_contract
from slopelander.controller.script_contract import ScriptState


class Actions(Protocol):
    """What the states may do to the vehicle and the legs (bound to MAVLink in actions.py)."""

    def check_preset(self, tau_up: float, tau_down: float) -> str | None: ...
    def can_set_angle(self) -> bool: ...
    def set_legs(self, tau_up: float, tau_down: float, angle_up_deg: float | None = None) -> None: ...
    def loosen_legs(self) -> None: ...
    def set_mode(self, mode: str) -> None: ...
    def descend(self, rate_mps: float) -> None: ...
    def hold(self, climb_mps: float) -> None: ...
    def reflex_arm(self) -> None: ...
    def reflex_abort(self) -> None: ...
    def reflex_end_reverse(self) -> None: ...
    def reflex_refresh(self) -> None: ...
    def release(self) -> None: ...
    def reverse(self, pct: float, ms: int) -> None: ...
    def disarm(self) -> None: ...
    def disarm_on_ground(self) -> None: ...
    def disarm_forced(self) -> None: ...
    def takeoff(self, height_m: float) -> None: ...
    def refused(self, key: str) -> bool: ...
    def statustext(self, text: str) -> None: ...


#: the on-board script contract this controller speaks (docs/onboard-script.md)
SCRIPT_CONTRACT = script_contract.SCRIPT_CONTRACT


@dataclass
class Inputs:
    """One snapshot of everything the machine reads; ``t`` is vehicle time (s)."""

    t: float
    link_ok: bool = True
    link_lost_why: str = ""  # which of the link's loss rules fired (Link.lost_why), for the record
    mode: str = "GUIDED"
    armed: bool = True
    estop: bool = False
    range_m: float | None = None
    range_ok: bool = False
    #: the range reading's own vehicle time (s, DISTANCE_SENSOR time_boot_ms); None: the step's
    range_t: float | None = None
    script_present: bool = True
    script_state: int = ScriptState.IDLE
    #: the contract version the on-board script reports (SL_VER); None until it has
    script_version: float | None = SCRIPT_CONTRACT
    legs_ready: bool = False
    legs_fault: str | None = None
    #: the uphill legs' angles as the board reports them (deg below the horizontal; empty: unknown)
    uphill_angles_deg: tuple[float, ...] = ()
    #: the downhill legs' angles as the board reports them (deg; empty: unknown)
    downhill_angles_deg: tuple[float, ...] = ()
    accel_mps2: float = 9.81
    #: the vehicle's speed (m/s) from LOCAL_POSITION_NED; None when none arrived recently
    speed_mps: float | None = 0.0
    #: the vehicle's vertical speed (m/s, up) from the same message; None when none arrived recently
    climb_mps: float | None = 0.0
    #: the vehicle's position (m, north-east-down) from the same message; None when unknown
    position_m: tuple[float, float, float] | None = (0.0, 0.0, 0.0)
    #: the body's largest tilt from level (deg) by the ATTITUDEs stamped near the range reading's
    #: own moment; None when none was (TAKEOFF and SETTLED read it with the range)
    tilt_deg: float | None = 0.0
    #: the vehicle's heading (deg from north, clockwise; the newest ATTITUDE yaw); None: unknown
    heading_deg: float | None = None
    #: the rangefinder's beam (unit vector north-east-down) by the ATTITUDE nearest the range
    #: reading's own moment (controller/roof.py ``beam_direction``); None: unknown
    beam_ned: tuple[float, float, float] | None = None
    #: height above home (m; GLOBAL_POSITION_INT's relative altitude, fresh); None: unknown
    above_home_m: float | None = None
    impact: bool = False
    takeoff_request: bool = False
    #: the slope measured before the landing (controller/slope_estimate.py) and how far the
    #: landing's slope may lie from it (deg); None when it was not measured (CHECKS skips it)
    slope_measured: Any = None
    slope_bound_deg: float | None = None

    @property
    def range_valid(self) -> bool:
        """A reading the landing may act on: flagged valid and a finite distance, not a stale
        number left in ``range_m`` by a sensor that has since failed."""
        r = self.range_m
        return self.range_ok and r is not None and math.isfinite(r) and r >= 0.0


@dataclass
class Context:
    """What the states share: settings, the vehicle's hands, the chosen preset, timers."""

    cfg: Any
    act: Actions
    preset: tuple[float, float] = (0.0, 0.0)
    #: the uphill legs' angle the landing needs (deg), None when any angle will do
    uphill_angle_deg: float | None = None
    next_preset: tuple[float, float] | None = None
    #: the landing site's slope (deg), None when unknown (the take-off then assumes
    #: ``takeoff.unknown_slope_deg``)
    slope_deg: float | None = None
    entered_at: float = 0.0
    #: the state the machine was in before the current one (None at the start)
    previous: str | None = None
    marks: dict[str, Any] = field(default_factory=dict)


G = 9.80665
#: the script's CUT, RVT and HOLD: its landing sequence, where a re-sent arm only renews validity
SCRIPT_LANDING = (ScriptState.CUT, ScriptState.RVT, ScriptState.HOLD)


def still(cfg: Any, inp: Inputs) -> bool:
    """At rest on the ground: the accelerometer reads 1 g (``settle.still_mps2``) AND the vehicle's
    speed is known and at most ``settle.still_speed_mps``. The accelerometer alone cannot tell a
    steady slide (no acceleration) from rest."""
    return (
        abs(inp.accel_mps2 - G) <= cfg["settle.still_mps2"]
        and inp.speed_mps is not None
        and inp.speed_mps <= cfg["settle.still_speed_mps"]
    )


def keep_reflex(ctx: Context, inp: Inputs, thrust_ended: bool = False) -> None:
    """Re-send the reflex arm every ``reflex.refresh_s``: after the cut it only renews the script's
    validity (a lapse in HOLD disarms: the script's answer to a silent companion), so a companion
    that is alive keeps the decision to disarm for itself. Once the reverse thrust is over
    (``thrust_ended``) the refresh says so too (duration 0): a refresh with the full duration could
    reach the script before the end command and put the thrust back on to its bound."""
    if inp.script_state not in SCRIPT_LANDING:  # never re-arm a script that has let go
        return
    if inp.t - ctx.marks.get("reflex_sent", -1e9) >= ctx.cfg["reflex.refresh_s"]:
        if thrust_ended:
            ctx.act.reflex_end_reverse()
        else:
            ctx.act.reflex_refresh()
        ctx.marks["reflex_sent"] = inp.t


def hand_to_loiter(ctx: Context, inp: Inputs) -> None:
    """In the air and in GUIDED, the vehicle is handed to the autopilot's LOITER (a hold setpoint
    first, then the mode): a landing that ends with something for the pilot to see to (legs not
    reset) must not leave the vehicle in GUIDED with nobody sending it anything."""
    if inp.armed and inp.mode == "GUIDED":
        ctx.act.hold(0.0)
        ctx.act.set_mode("LOITER")


class State:
    """A state; subclasses override what they need. ``enter`` returns None or a refusal reason."""

    name = "STATE"
    #: True while the vehicle is in the air under the companion's descent (failsafes act).
    airborne_descent = False
    #: True once the on-board reflex owns the motors (the companion must not interfere).
    reflex_owns = False
    #: where a refused ``enter`` goes
    refused_to = "ABORTED"

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        return None

    def step(self, ctx: Context, inp: Inputs) -> tuple[str, str] | None:
        """(next state name, reason) or None to stay."""
        return None

    def leave(self, ctx: Context, inp: Inputs) -> None:
        return None
