"""Arm in GUIDED, the way a ground station must on either autopilot: the shared start of every
simulated flight (the rig's, the demo's).

ArduCopter's start-up sets its initial mode after a GUIDED asked for too early, and it refuses to
arm in GUIDED until its EKF has an origin (20-40 s of vehicle time after boot); the simulated
vehicle accepts both at once. So: ask again, a second of vehicle time apart, until the HEARTBEAT
shows GUIDED and armed.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

GUIDED = 4
#: ArduCopter's force-arm magic (param2 of an arm): past the pre-arm checks, e.g. a lean on a roof
FORCE_ARM = 2989


def armed_in(link) -> tuple[int | None, bool]:
    """(custom mode, armed) from the newest HEARTBEAT."""
    hb = link.last.get("HEARTBEAT")
    if hb is None:
        return None, False
    return hb.custom_mode, bool(hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


#: the throttle stick at the bottom (RC3_MIN of every parameter file)
THROTTLE_DOWN_US = 1000


def throttle_override(link, pwm: int) -> None:
    """Override RC channel 3 with ``pwm`` (0: release it), the other channels untouched, as the
    pilot's ground station: ArduCopter takes RC overrides only from its system id
    (MAV_GCS_SYSID, 255), not from the companion's."""
    if link.info is None:
        return
    msg = GCS_ENCODER.rc_channels_override_encode(
        link.info.system, link.info.component, *throttle_channels(pwm)
    )
    link.conn.write(msg.pack(GCS_ENCODER))


def throttle_channels(pwm: int) -> list[int]:
    """RC_CHANNELS_OVERRIDE's eight channels with only the throttle (3) set; UINT16_MAX leaves a
    channel as it is."""
    ignore = 65535
    return [ignore, ignore, pwm, *([ignore] * 5)]


#: packs messages as the ground station (system 255, MAVProxy's component 190)
GCS_ENCODER = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)


def arm_in_guided(
    link,
    poll: Callable[[], None],
    force: bool = False,
    vehicle_s: float = 120.0,
    wall_s: float = 300.0,
) -> None:
    """Put the vehicle in GUIDED and arm it; raises TimeoutError (with the autopilot's last words)
    when it has not within ``vehicle_s`` of vehicle time or ``wall_s`` of wall time.

    The pilot holds the throttle stick down meanwhile (an RC override of channel 3, released once
    armed): ArduCopter arms only with it down, from a ground station in GUIDED too
    (AP_Arming::rc_arm_checks, RC_OPTIONS bit 5), and a scenario's pilot may hold it centred."""
    t0, end = link.clock.now(), time.monotonic() + wall_s
    asked, handle = -1e9, None
    while True:
        mode, armed = armed_in(link)
        if mode == GUIDED and armed:
            throttle_override(link, 0)  # released: the scenario's stick again
            return
        now = link.clock.now()
        if now - t0 > vehicle_s or time.monotonic() > end:
            said = "; ".join(list(link.statustext)[-3:])
            raise TimeoutError(f"not armed in GUIDED within {vehicle_s:g} s (mode {mode}): {said}")
        if (handle is None or handle.done) and now - asked >= 1.0:
            asked = now
            if mode != GUIDED:
                handle = link.command(mavlink.MAV_CMD_DO_SET_MODE, 1, GUIDED)
            else:
                throttle_override(link, THROTTLE_DOWN_US)
                handle = link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, FORCE_ARM if force else 0)
        poll()
        time.sleep(0.002)
