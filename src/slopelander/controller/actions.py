"""The state machine's hands bound to the real vehicle: MAVLink through :class:`Link`, legs through the board.

Every command is non-blocking: it returns at once and its handle is kept in :attr:`MavActions.pending`
for the caller to inspect; nothing here waits.
"""

from __future__ import annotations

from slopelander.controller.config import Config
from slopelander.controller.link import CommandHandle, Link, mavlink
from slopelander.controller.script_contract import ScriptClient, ScriptRequest
from slopelander.legs.errors import LegBoardError

MODES = {"GUIDED": 4, "LAND": 9, "LOITER": 5, "BRAKE": 17, "RTL": 6}
DESCENT_TYPE_MASK = 0x0DC7  # velocity only
#: MAV_CMD_COMPONENT_ARM_DISARM param 2 that skips the autopilot's disarm checks
FORCE_DISARM = 21196


class MavActions:
    """Implements :class:`slopelander.controller.states.base.Actions`."""

    def __init__(self, link: Link, cfg: Config, legs=None) -> None:
        self.link = link
        self.cfg = cfg
        self.legs = legs
        self.leg_op = None
        #: why the last leg command could not even start (out of range, queue full), else None
        self.leg_error: str | None = None
        self._then: tuple[float, float] | None = None  # torques to set once the angle is set
        self.pending: dict[str, CommandHandle | ScriptRequest] = {}
        self._last_descent = -1.0
        #: the on-board script's requests, each ACK matched to its own request (None without a
        #: link: the leg actions alone, as on the bench)
        self.script = (
            ScriptClient(
                link, retries=int(cfg["link.command_retries"]), timeout_s=cfg["link.command_timeout_s"]
            )
            if link is not None
            else None
        )
        self._setup: ScriptRequest | None = None

    def _cmd(self, key: str, command: int, *params: float) -> CommandHandle:
        h = self.link.command(
            command,
            *params,
            retries=int(self.cfg["link.command_retries"]),
            timeout_s=self.cfg["link.command_timeout_s"],
        )
        self.pending[key] = h
        return h

    def check_preset(self, tau_up: float, tau_down: float) -> str | None:
        """Why the legs cannot take this preset (outside their calibration), or None."""
        if self.legs is None:
            return None
        try:
            self.legs.check_preset(tau_up, tau_down)
        except LegBoardError as exc:
            return str(exc)
        return None

    def can_set_angle(self) -> bool:
        """Whether the board reports an angle actuator (the ANGLE_STOP capability)."""
        info = getattr(self.legs, "info", None)
        return bool(info is not None and info.angle_stop)

    def set_legs(self, tau_up: float, tau_down: float, angle_up_deg: float | None = None) -> None:
        """Set the torques; with an angle (and a board that can), first the uphill rest angle."""
        self._then = None
        if self.legs is not None and angle_up_deg is not None and self.can_set_angle():
            uphill = dict.fromkeys(self.legs.pairs.uphill, angle_up_deg)
            timeout = self.cfg["legs.ready_timeout_s"]
            self._leg_command(lambda: self.legs.start_angles(uphill, timeout=timeout))
            if self.leg_op is not None:
                self._then = (tau_up, tau_down)
        elif self.legs is not None:
            self._leg_command(
                lambda: self.legs.start_presets(
                    tau_up,
                    tau_down,
                    tolerance_nm=self.cfg["legs.tolerance_nm"],
                    timeout=self.cfg["legs.ready_timeout_s"],
                )
            )

    @property
    def legs_busy(self) -> bool:
        """A multi-step leg preset (angle, then torques) is still on its first step."""
        return self._then is not None

    def advance(self) -> None:
        """Start the torques once the angle is set; called every poll."""
        op = self.leg_op
        if self._then is not None and op is not None and op.done:
            up, down = self._then
            self._then = None
            if op.error is None:
                self.set_legs(up, down)

    def loosen_legs(self) -> None:
        self._then = None
        if self.legs is not None:
            self._leg_command(lambda: self.legs.start_loosen(timeout=self.cfg["legs.ready_timeout_s"]))

    def _leg_command(self, start) -> None:
        """Start a leg operation; one that cannot start is a leg failure the machine reads."""
        try:
            self.leg_op, self.leg_error = start(), None
        except LegBoardError as exc:
            self.leg_op, self.leg_error = None, str(exc)

    def set_mode(self, mode: str) -> None:
        self._cmd("mode", mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, MODES[mode])

    def descend(self, rate_mps: float) -> None:
        """Velocity setpoint down; re-sent at most at ``descent.resend_hz`` however often it is called."""
        now = self.link.monotonic()
        if now - self._last_descent < 1.0 / self.cfg["descent.resend_hz"]:
            return
        self._send_velocity(now, rate_mps)

    def hold(self, climb_mps: float) -> None:
        """A climb setpoint (m/s up; 0 holds) sent now, whenever the last setpoint went: it
        replaces a descent target that would otherwise run on until GUID_TIMEOUT."""
        self._send_velocity(self.link.monotonic(), -climb_mps)

    def _send_velocity(self, now: float, rate_mps: float) -> None:
        self._last_descent = now
        info = self.link.info
        if info is None:
            return
        self.link.conn.mav.set_position_target_local_ned_send(
            int(self.link.clock.now() * 1000) & 0xFFFFFFFF,
            info.system,
            info.component,
            mavlink.MAV_FRAME_LOCAL_NED,
            DESCENT_TYPE_MASK,
            0,
            0,
            0,
            0,
            0,
            float(rate_mps),
            0,
            0,
            0,
            0,
            0,
        )

    def reflex_arm(self, reverse_ms: float | None = None) -> None:
        """Arm (or refresh) the reflex; the reverse-thrust duration sent is the longest allowed
        (``reflex.reverse_max_ms``, the script's bound if the companion goes silent). The
        landing's SETUP (ramp, descent rate) goes first until the script has accepted one, and
        again after an arm it refused (a rebooted script has none)."""
        c = self.cfg.reflex
        s, arm = self._setup, self.script.last.get("arm")
        if s is None or (s.done and not s.ok) or (arm is not None and arm.state == "rejected"):
            self._setup = self.script.setup(c["reverse_ramp_ms"], self.cfg["descent.rate_mps"])
        self.pending["reflex"] = self.script.arm(
            c["cut_height_m"],
            c["impact_threshold_mps2"],
            c["reverse_thrust_pct"],
            c["reverse_max_ms"] if reverse_ms is None else reverse_ms,
            c["validity_ms"],
        )

    def reflex_refresh(self) -> None:
        """Renew the script's validity during its landing sequence (the same arm command: in
        CUT and HOLD the script only extends the validity)."""
        self.reflex_arm()

    def reflex_end_reverse(self) -> None:
        """End the script's reverse thrust now; the script ramps it down over
        ``reflex.reverse_ramp_ms``, then holds the motors stopped (HOLD); it renews the validity."""
        c = self.cfg.reflex
        self.pending["reflex"] = self.script.end_reverse(
            c["cut_height_m"], c["impact_threshold_mps2"], c["reverse_thrust_pct"], c["validity_ms"]
        )

    def reflex_abort(self) -> None:
        """Abort an armed reflex; from the cut on the script refuses (it keeps the motors held)."""
        self.pending["reflex"] = self.script.abort()

    def release(self) -> None:
        """Give commanded outputs back to the autopilot; from the cut on the script refuses."""
        self.pending["actuator"] = self.script.release()

    def release_for_takeoff(self) -> None:
        """Give the motors back for a take-off: a held vehicle only when level enough
        (:data:`~slopelander.controller.script_contract.TAKEOFF_RELEASE_TILT_DEG`)."""
        self.pending["actuator"] = self.script.release_for_takeoff()

    def reverse(self, pct: float, ms: int) -> None:
        self.pending["actuator"] = self.script.reverse(pct, max(20, min(5000, int(ms))))

    def disarm(self) -> None:
        """Ask the script to disarm the vehicle: it does while it holds the motors stopped and the
        vehicle is still; ArduCopter does not refuse a script's disarm the way it refuses a ground
        station's before its land detector fires (docs/onboard-script.md, "Disarm")."""
        self.pending["disarm"] = self.script.disarm()

    def disarm_on_ground(self) -> None:
        """The companion's own disarm, unforced (param 2 is 0, not 21196): ArduCopter runs its
        checks and refuses it unless its land detector says landed (AP_Arming_Copter::disarm),
        for a vehicle whose script is idle and so refuses to disarm it."""
        self._cmd("disarm_on_ground", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0)

    def disarm_forced(self) -> None:
        """The companion's forced disarm (param 2 = 21196: no land-detector check), for a vehicle
        on the roof whose script is dead or failed, read still and down (at or below the cut
        height, or tipped over: states/settled.py, ``Settled.without_script``): what the script
        would have done."""
        self._cmd("disarm_forced", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, FORCE_DISARM)

    def takeoff(self, height_m: float) -> None:
        self.set_mode("GUIDED")
        self._cmd("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        self._cmd("takeoff", mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, height_m)

    def statustext(self, text: str) -> None:
        self.link.send_statustext(text)

    def refused(self, key: str) -> bool:
        """Whether the last command of this kind (``"takeoff"``, ``"arm"``, ...) was answered
        with anything but ACCEPTED or never answered."""
        h = self.pending.get(key)
        return bool(h is not None and h.done and not h.ok)
