"""ArduCopter SITL's start-up without the wait: the rules, without I/O.

Nobody needs to watch ArduCopter's EKF align, find GPS and settle on a position in real time
(about 40 s of vehicle time). So a vehicle boots at a high speed-up (``SIM_SPEEDUP``, in lock-step
with the physics: as fast as the two can step) and is set to the flight's speed-up before anyone
may arm it; MAVProxy's ``sitl_autospeedup`` module does the same. The speed-up ends once it could
arm in GUIDED:

- the EKF has a horizontal position (EKF_STATUS_REPORT): without one GUIDED refuses to arm, "Need
  Position Estimate" (``Copter::ekf_has_absolute_position``, ArduCopter/system.cpp, takes the
  absolute or the predicted absolute position while disarmed); it comes at 38-41 s of boot time;
- and SYS_STATUS's pre-arm bit is set (it is at 20-25 s on the pad). A vehicle with a position
  whose checks still fail at ``CAP_S`` (one leaning on a roof, armed with the force flag) goes on.

A vehicle with no position at ``GIVE_UP_S`` goes on all the same: its caller's own time-outs then
say what is wrong, at the flight's speed.

The frame rate stays the flight's: booted at 200 frames a second (``SIM_RATE_HZ``) and set back to
800 once it had a position, ArduCopter went on measuring its gyro at 203-230 Hz for two minutes and
refused to arm ("Gyro 0 rate 230Hz < loop ratex1.8 720Hz", 2026-11-27): it does not re-measure it.
"""

from __future__ import annotations

from dataclasses import dataclass

#: SYS_STATUS sensor bit ArduPilot sets while its pre-arm checks pass
#: (MAV_SYS_STATUS_PREARM_CHECK, GCS_MAVLINK::update_sensor_status_flags)
PREARM_CHECK = 0x10000000
#: EKF_STATUS_REPORT flags of an absolute horizontal position, current or predicted
#: (EKF_POS_HORIZ_ABS, EKF_PRED_POS_HORIZ_ABS)
POSITION_FLAGS = 16 | 512
#: s of boot time after which a vehicle with a position goes on with its pre-arm checks failing
CAP_S = 45.0
#: s of boot time after which the boot ends without a position
GIVE_UP_S = 120.0


@dataclass
class FastBoot:
    """Feed it what ArduCopter says (:meth:`heard`); send what :attr:`pending` asks for until
    ArduCopter confirms it; :attr:`done` once the vehicle runs at ``flight_speedup``."""

    flight_speedup: float
    boot_s: float = 0.0
    prearm_ok: bool = False
    position_ok: bool = False
    done_at: float | None = None  # boot s when the flight's speed-up was confirmed
    why: str = ""

    @property
    def done(self) -> bool:
        return self.done_at is not None

    def reason(self) -> str | None:
        """Why the boot may end now, or None while it may not."""
        if self.position_ok and self.prearm_ok:
            return "pre-arm checks pass, EKF has a position"
        if self.position_ok and self.boot_s >= CAP_S:
            return f"EKF has a position, pre-arm checks still failing at {CAP_S:g} s"
        if self.boot_s >= GIVE_UP_S:
            return f"no EKF position at {GIVE_UP_S:g} s"
        return None

    @property
    def pending(self) -> tuple[str, float] | None:
        """The parameter to set now (name, value), or None."""
        if self.done or self.reason() is None:
            return None
        return ("SIM_SPEEDUP", self.flight_speedup)

    def heard(self, kind: str, msg: object) -> None:
        """One message from ArduCopter (pymavlink's, or anything with the same fields)."""
        if kind == "SYSTEM_TIME":
            self.boot_s = msg.time_boot_ms / 1000.0
        elif kind == "SYS_STATUS":
            self.prearm_ok = bool(msg.onboard_control_sensors_health & PREARM_CHECK)
        elif kind == "EKF_STATUS_REPORT":
            self.position_ok = bool(msg.flags & POSITION_FLAGS)
        elif kind == "PARAM_VALUE" and not self.done:
            why = self.reason()
            name = msg.param_id.rstrip("\x00")
            confirmed = name == "SIM_SPEEDUP" and abs(msg.param_value - self.flight_speedup) < 1e-3
            if why is not None and confirmed:
                self.done_at, self.why = self.boot_s, why
