"""What the link knows of MAVLink messages: which ones a landing reads, where each carries the
autopilot's time, and what the companion found at the other end (:class:`AutopilotInfo`)."""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass

# The MAVLink 2 message set, whatever was imported before: only it has COMMAND_ACK.result_param2,
# the request number the on-board script echoes (a MAVLink 1 peer is still understood).
os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

from slopelander.errors import SlopelanderError

mavlink = mavutil.mavlink

#: what a landing reads from the autopilot; everything else can be dropped before decoding
LANDING_MESSAGES = frozenset(
    {
        "HEARTBEAT",
        "COMMAND_ACK",
        "STATUSTEXT",
        "AUTOPILOT_VERSION",
        "SYSTEM_TIME",
        "NAMED_VALUE_FLOAT",
        "RAW_IMU",
        "DISTANCE_SENSOR",
        "LOCAL_POSITION_NED",
        "ATTITUDE",
        "RC_CHANNELS",
        "GLOBAL_POSITION_INT",
    }
)
#: messages every one of which a reader needs, not only the newest (the impact detector reads every
#: IMU sample, however seldom the landing loop wakes): the link keeps the last few of each
#: and the attitude a range reading was taken with is looked up among the recent ATTITUDEs
KEEP_RECENT = ("RAW_IMU", "ATTITUDE")  # what the landing reads; HIGHRES_IMU is not
RECENT_LEN = 64
#: Messages that carry the autopilot's time, and the field holding it.
USEC_FIELDS = {
    "SYSTEM_TIME": "time_boot_ms",
    "RAW_IMU": "time_usec",
    "HIGHRES_IMU": "time_usec",
    "ATTITUDE": "time_boot_ms",
    "LOCAL_POSITION_NED": "time_boot_ms",
    "SERVO_OUTPUT_RAW": "time_usec",
    "DISTANCE_SENSOR": "time_boot_ms",
    "NAMED_VALUE_FLOAT": "time_boot_ms",
    "RC_CHANNELS": "time_boot_ms",
    "GLOBAL_POSITION_INT": "time_boot_ms",
}


class LinkError(SlopelanderError):
    """The link cannot be opened or used (bad connection string, no autopilot)."""


def stamp_usec(msg, fld: str) -> int | None:
    """The autopilot's time on ``msg`` in microseconds (None: not stamped, 0 or less)."""
    v = int(getattr(msg, fld))
    if v <= 0:
        return None
    return v if fld == "time_usec" else v * 1000


def message_ids(names: Iterable[str]) -> frozenset[int]:
    """MAVLink message ids for message names; an unknown name is a :class:`LinkError`."""
    ids = set()
    for name in names:
        msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}", None)
        if not isinstance(msg_id, int):
            raise LinkError(f"unknown MAVLink message name {name!r} in the messages to decode")
        ids.add(msg_id)
    return frozenset(ids)


@dataclass
class AutopilotInfo:
    """What the companion found at the other end of the link."""

    system: int
    component: int
    vehicle_type: int
    autopilot: int
    firmware: str = "unknown"
    script_version: float | None = None

    def describe(self) -> str:
        """One line for the pilot."""
        vt = mavlink.enums["MAV_TYPE"].get(self.vehicle_type)
        ap = mavlink.enums["MAV_AUTOPILOT"].get(self.autopilot)
        # "not heard", not "absent": a script announces its version once a second, and a line
        # printed before that would call a running script missing (CHECKS refuses a silent one)
        script = "not heard" if self.script_version is None else f"v{self.script_version:g}"
        return (
            f"system {self.system} component {self.component}: "
            f"{vt.name if vt else self.vehicle_type}, {ap.name if ap else self.autopilot}, "
            f"firmware {self.firmware}, on-board script {script}"
        )
