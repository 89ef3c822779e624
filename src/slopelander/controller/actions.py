"""The state machine's hands bound to the real vehicle: MAVLink through :class:`Link`, legs through the board.

Every command is non-blocking: it returns at once and its handle is kept in :attr:`MavActions.pending`
for the caller to inspect; nothing here waits.
"""

from __future__ import annotations

from slopelander.controller.config import Config
from slopelander.controller.link import CommandHandle, Link, mavlink

MODES = {"GUIDED": 4, "LAND": 9, "LOITER": 5, "BRAKE": 17, "RTL": 6}
DESCENT_TYPE_MASK = 0x0DC7  # velocity only
USER_1, USER_2 = 31010, 31011
ACTION_RELEASE, ACTION_STOP, ACTION_REVERSE = 0, 1, 2


class MavActions:
    """Implements :class:`slopelander.controller.states.base.Actions`."""

    def __init__(self, link: Link, cfg: Config, legs=None) -> None:
        self.link = link
        self.cfg = cfg
        self.legs = legs
        self.leg_op = None
        self.pending: dict[str, CommandHandle] = {}
        self._last_descent = -1.0

    def _cmd(self, key: str, command: int, *params: float) -> CommandHandle:
        h = self.link.command(command, *params, retries=int(self.cfg["link.command_retries"]),
                              timeout_s=self.cfg["link.command_timeout_s"])
        self.pending[key] = h
        return h

    def set_legs(self, tau_up: float, tau_down: float) -> None:
        if self.legs is not None:
            self.leg_op = self.legs.start_presets(
                tau_up, tau_down, tolerance_nm=self.cfg["legs.tolerance_nm"],
                timeout=self.cfg["legs.ready_timeout_s"])

    def loosen_legs(self) -> None:
        if self.legs is not None:
            self.leg_op = self.legs.start_loosen()

    def set_mode(self, mode: str) -> None:
        self._cmd("mode", mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, MODES[mode])

    def descend(self, rate_mps: float) -> None:
        """Velocity setpoint down; re-sent at most at ``descent.resend_hz`` however often it is called."""
        now = self.link.monotonic()
        if now - self._last_descent < 1.0 / self.cfg["descent.resend_hz"]:
            return
        self._last_descent = now
        info = self.link.info
        if info is None:
            return
        self.link.conn.mav.set_position_target_local_ned_send(
            int(self.link.clock.now() * 1000) & 0xFFFFFFFF, info.system, info.component,
            mavlink.MAV_FRAME_LOCAL_NED, DESCENT_TYPE_MASK, 0, 0, 0, 0, 0, float(rate_mps), 0, 0, 0, 0, 0)

    def reflex_arm(self) -> None:
        c = self.cfg.reflex
        self._cmd("reflex", USER_2, 1, c["cut_height_m"], c["impact_threshold_mps2"],
                  c["reverse_thrust_pct"], c["reverse_thrust_ms"], c["validity_ms"])

    def reflex_abort(self) -> None:
        self._cmd("reflex", USER_2, 0)

    def release(self) -> None:
        self._cmd("actuator", USER_1, ACTION_RELEASE, 0, 1000)

    def reverse(self, pct: float, ms: int) -> None:
        self._cmd("actuator", USER_1, ACTION_REVERSE, pct, max(20, min(5000, int(ms))))

    def disarm(self) -> None:
        self._cmd("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)

    def takeoff(self, height_m: float) -> None:
        self.set_mode("GUIDED")
        self._cmd("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        self._cmd("takeoff", mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, height_m)

    def statustext(self, text: str) -> None:
        self.link.send_statustext(text)
