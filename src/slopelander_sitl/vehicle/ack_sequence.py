"""One scripted sequence of the commands the companion sends, run against any autopilot (the
simulated vehicle or a real ArduCopter SITL), recording the COMMAND_ACK result of each.

The same sequence run on both and compared command by command keeps the stand-in from drifting
kinder than ArduCopter (tests/vehicle/test_rules_vs_arducopter.py). Between recorded commands it
flies what the answers depend on: a take-off, and a GUIDED descent until the autopilot's land
detector reports ON_GROUND.

    python -m slopelander_sitl.vehicle.ack_sequence --connect tcp:127.0.0.1:5760 [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil

from slopelander_sitl.guided import throttle_channels

M = mavutil.mavlink
FORCE_DISARM = 21196  # GCS.h magic_force_arm_disarm_value
TEXT_AFTER_ACK_S = 0.3
RESULT_NAMES = {k: e.name.replace("MAV_RESULT_", "") for k, e in M.enums["MAV_RESULT"].items()}


@dataclass
class Answer:
    """One recorded command: what was sent, the COMMAND_ACK result (None: no answer) and the
    STATUSTEXTs that came with it."""

    name: str
    command: int
    params: list[float]
    result: int | None
    texts: list[str] = field(default_factory=list)

    @property
    def result_name(self) -> str:
        return "NO ANSWER" if self.result is None else RESULT_NAMES.get(self.result, str(self.result))


class SequenceError(RuntimeError):
    """The vehicle did not reach a state the sequence needs (ready to arm, climbed, landed)."""


class _Client:
    def __init__(
        self, conn, target_system: int, target_component: int, ack_timeout_s: float, text_after_ack_s: float
    ) -> None:
        self.conn, self.ts, self.tc, self.ack_timeout_s = conn, target_system, target_component, ack_timeout_s
        self.text_after_ack_s = text_after_ack_s
        self.last: dict[str, object] = {}

    def _recv(self, timeout: float):
        m = self.conn.recv_match(blocking=True, timeout=timeout)
        if m is not None and m.get_type() != "BAD_DATA":
            self.last[m.get_type()] = m
        return m

    def command(self, name: str, cmd: int, *params: float) -> Answer:
        p = [float(x) for x in params] + [0.0] * (7 - len(params))
        self.conn.mav.command_long_send(self.ts, self.tc, cmd, 0, *p)
        texts: list[str] = []
        deadline = time.monotonic() + self.ack_timeout_s
        while time.monotonic() < deadline:
            m = self._recv(0.2)
            if m is None:
                continue
            if m.get_type() == "STATUSTEXT":
                texts.append(m.text)
            elif m.get_type() == "COMMAND_ACK" and m.command == cmd:
                # ArduPilot queues its texts behind the ACK: gather them for a short while
                end = time.monotonic() + self.text_after_ack_s
                while time.monotonic() < end:
                    t = self._recv(0.05)
                    if t is not None and t.get_type() == "STATUSTEXT":
                        texts.append(t.text)
                return Answer(name, cmd, p, int(m.result), texts)
        return Answer(name, cmd, p, None, texts)

    def wait(
        self, what: str, cond: Callable[[], bool], timeout_s: float, every: Callable[[], None] | None = None
    ) -> None:
        deadline = time.monotonic() + timeout_s
        next_send = 0.0
        while time.monotonic() < deadline:
            if every is not None and time.monotonic() >= next_send:
                every()
                next_send = time.monotonic() + 0.2
            self._recv(0.05)
            if cond():
                return
        raise SequenceError(f"the vehicle did not {what} within {timeout_s:.0f} s")

    def rc_throttle(self, pwm: int, settle_s: float = 0.5) -> None:
        """Override RC channel 3 (the throttle) with ``pwm``, the other channels untouched, and
        give the autopilot ``settle_s`` to read it (sent every 0.1 s meanwhile)."""
        end = time.monotonic() + settle_s
        while time.monotonic() < end:
            self.conn.mav.rc_channels_override_send(self.ts, self.tc, *throttle_channels(pwm))
            self._recv(0.1)

    def height(self) -> float | None:
        lp = self.last.get("LOCAL_POSITION_NED")
        return None if lp is None else -lp.z

    def landed_state(self) -> int | None:
        es = self.last.get("EXTENDED_SYS_STATE")
        return None if es is None else es.landed_state

    def armed(self) -> bool:
        hb = self.last.get("HEARTBEAT")
        return bool(hb is not None and hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)


def run_sequence(
    conn,
    target_system: int = 1,
    target_component: int = 1,
    ready_timeout_s: float = 120.0,
    flight_timeout_s: float = 60.0,
    ack_timeout_s: float = 5.0,
    progress: Callable[[str], None] | None = None,
    text_after_ack_s: float = TEXT_AFTER_ACK_S,
) -> list[Answer]:
    """Run the sequence on a pymavlink connection to a disarmed vehicle on the ground; return the
    recorded answers in order. Raises SequenceError when the vehicle never gets ready or never
    climbs or lands (the answers after that would compare nothing). ``text_after_ack_s``: how
    long after each ACK its STATUSTEXTs are gathered (a recording keeps them for the reader; a
    comparison of the results alone passes 0 and saves 0.3 s a command)."""
    c = _Client(conn, target_system, target_component, ack_timeout_s, text_after_ack_s)
    say = progress or (lambda s: None)
    out: list[Answer] = []

    def rec(name: str, cmd: int, *params: float) -> Answer:
        a = c.command(name, cmd, *params)
        out.append(a)
        say(f"{name}: {a.result_name}")
        return a

    guided = (M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4)
    # not recorded: until the autopilot has a position estimate it refuses GUIDED and arming
    # (real ArduCopter SITL: about 40 s after boot); retry both, then disarm
    say("waiting until GUIDED and arming are accepted")
    deadline = time.monotonic() + ready_timeout_s
    while True:
        ok = c.command("ready_mode", *guided).result == M.MAV_RESULT_ACCEPTED
        if ok and c.command("ready_arm", M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED:
            break
        if time.monotonic() > deadline:
            raise SequenceError(f"GUIDED and arming not accepted within {ready_timeout_s:.0f} s")
        time.sleep(2.0)
    c.command("ready_disarm", M.MAV_CMD_COMPONENT_ARM_DISARM, 0, FORCE_DISARM)
    c.wait("disarm", lambda: not c.armed(), 10.0)

    interval = M.MAV_CMD_SET_MESSAGE_INTERVAL
    rec("interval_position_10hz", interval, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 100_000)
    rec("interval_ext_state_5hz", interval, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 200_000)
    rec("interval_attitude_50hz", interval, M.MAVLINK_MSG_ID_ATTITUDE, 20_000)
    rec("interval_imu_200hz", interval, M.MAVLINK_MSG_ID_HIGHRES_IMU, 5_000)
    rec("interval_imu_250hz", interval, M.MAVLINK_MSG_ID_HIGHRES_IMU, 4_000)
    rec("interval_imu_333hz", interval, M.MAVLINK_MSG_ID_HIGHRES_IMU, 3_000)
    rec("interval_imu_400hz", interval, M.MAVLINK_MSG_ID_HIGHRES_IMU, 2_500)
    rec("interval_imu_off", interval, M.MAVLINK_MSG_ID_HIGHRES_IMU, -1)
    rec("mode_unknown_99", M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 99)
    rec("mode_without_custom_flag", M.MAV_CMD_DO_SET_MODE, 0, 4)
    rec("mode_guided", *guided)
    rec("takeoff_disarmed", M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 2.0)
    rec("disarm_disarmed", M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    rec("unknown_command", M.MAV_CMD_USER_5)
    # the pilot's throttle stick centred (an RC override; ArduCopter keeps it RC_OVERRIDE_TIME,
    # 3 s): GUIDED arming from the ground station is refused all the same (RC_OPTIONS bit 5)
    c.rc_throttle(1500)
    rec("arm_throttle_centred", M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    c.rc_throttle(1000)
    rec("arm", M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    rec("arm_armed", M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    rec("servo_on_motor_1", M.MAV_CMD_DO_SET_SERVO, 1, 1500)
    rec("takeoff_to_0m", M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0.0)
    c.wait("report its height", lambda: c.height() is not None, 10.0)
    ground = c.height()
    if rec("takeoff_2m", M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 2.0).result == M.MAV_RESULT_ACCEPTED:
        c.wait("climb 1.5 m", lambda: c.height() > ground + 1.5, flight_timeout_s)
    rec("takeoff_in_air", M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 3.0)
    rec("disarm_in_air", M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    rec("mode_guided_in_air", *guided)

    def descend() -> None:  # what the companion sends: velocity only, 0.5 m/s down, >= 5 Hz
        c.conn.mav.set_position_target_local_ned_send(
            0, c.ts, c.tc, M.MAV_FRAME_LOCAL_NED, 0x0DC7, 0, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0
        )

    say("descending in GUIDED until the land detector fires")
    c.wait(
        "land (EXTENDED_SYS_STATE ON_GROUND)",
        lambda: c.landed_state() == M.MAV_LANDED_STATE_ON_GROUND,
        flight_timeout_s,
        every=descend,
    )
    rec("disarm_landed", M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    c.wait("disarm", lambda: not c.armed(), 10.0)
    rec("arm_again", M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    if rec("takeoff_1m", M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 1.0).result == M.MAV_RESULT_ACCEPTED:
        c.wait("climb 0.5 m", lambda: c.height() > ground + 0.5, flight_timeout_s)
    rec("disarm_forced_in_air", M.MAV_CMD_COMPONENT_ARM_DISARM, 0, FORCE_DISARM)
    c.wait("disarm", lambda: not c.armed(), 10.0)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m slopelander_sitl.vehicle.ack_sequence", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--connect", required=True, help="autopilot's pymavlink URL, e.g. tcp:127.0.0.1:5760")
    ap.add_argument("--json", action="store_true", help="print the answers as JSON")
    ap.add_argument("--ready-timeout", type=float, default=120.0, help="s until it arms (default 120)")
    a = ap.parse_args(argv)
    try:
        conn = mavutil.mavlink_connection(a.connect, source_system=255, source_component=190)
    except Exception as exc:  # pymavlink raises many kinds for a bad address
        print(f"cannot connect to {a.connect!r}: {exc}", file=sys.stderr)
        return 2
    if conn.wait_heartbeat(timeout=30) is None:
        print(f"no HEARTBEAT from {a.connect} within 30 s", file=sys.stderr)
        return 2
    try:
        answers = run_sequence(
            conn,
            conn.target_system,
            conn.target_component,
            ready_timeout_s=a.ready_timeout,
            progress=None if a.json else print,
        )
    except SequenceError as exc:
        print(f"sequence stopped: {exc}", file=sys.stderr)
        return 1
    finally:
        conn.close()
    if a.json:
        print(json.dumps([asdict(x) | {"result_name": x.result_name} for x in answers], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
