"""One landing: reads the link and the legs into :class:`Inputs`, steps the machine, until it ends.

This is what ``slopelander land`` runs. The loop polls (never blocks) at about 1 kHz of local time
and steps the machine whenever vehicle time advanced.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
from collections.abc import Callable
from typing import IO

from pymavlink import mavutil

from slopelander.controller.actions import MODES, MavActions
from slopelander.controller.config import Config
from slopelander.controller.impact import ImpactDetector, raw_imu_accel
from slopelander.controller.link import Link, mavlink
from slopelander.controller.machine import Machine
from slopelander.controller.pilot_switch import APPLY_IN, WAIT_AGAIN, PresetSwitch
from slopelander.controller.roof import beam_direction
from slopelander.controller.script_contract import ScriptState
from slopelander.controller.slope_estimate import SlopeEstimate
from slopelander.controller.states.aborted import Aborted
from slopelander.controller.states.base import Context, Inputs
from slopelander.legs.errors import LegBoardError

#: ArduCopter's mode numbers by name (pymavlink's table of ArduCopter/mode.h), so that a refusal
#: reads "mode STABILIZE, GUIDED needed"; a number it does not know reads as "number N"
MODE_NAMES = {**mavutil.mode_mapping_acm, **{v: k for k, v in MODES.items()}}
ENDINGS = ("LANDED", "ABORTED", "ESTOP", "READY")
SCRIPT_ESTOP = ScriptState.ESTOP


#: the longest the landing loop waits for input between polls: the leg board's queued writes and
#: the descent setpoint's re-sends still go out at 200 Hz or more
POLL_WAIT_S = 0.005
#: after an interrupt in the air, how long (local s) the companion waits to see LOITER
INTERRUPT_WAIT_S = 3.0
#: how fast the loop's estimate of the vehicle's speed (vehicle per local seconds) follows a change
RATE_GAIN = 0.2
MAX_RATE = 50.0
#: a leg board that failed is reconnected only between landings: in a landing the failure policy
#: (docs/failsafes.md) applies, and a fresh handshake must not reset legs under load
RECONNECT_IN = ("LANDED", "READY", "ABORTED", "ESTOP")
#: the reconnect's handshake, local seconds (the autopilot's clock is not read meanwhile)
HANDSHAKE_S = 0.5
#: local seconds a run that reached ABORTED goes on polling while the abort is still holding the
#: reflex (states/aborted.py: until the vehicle climbs or holds) or climbing before LOITER
#: (``Aborted.rising``), so the loop does not end with the reflex armed and nobody refreshing the
#: climb setpoint; more than the rise's own bound (``RISE_MAX_S``, vehicle time)
ABORT_SETTLE_S = 8.0


def tilt_at(attitudes: list) -> float | None:
    """The largest tilt from level (deg) among ``attitudes`` (ATTITUDE messages); None when there
    are none or one is not finite: an unknown attitude is not level."""
    worst = None
    for att in attitudes:
        c = math.cos(att.roll) * math.cos(att.pitch)  # the body's z axis against the vertical
        if not math.isfinite(c):
            return None
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, c))))
        worst = tilt if worst is None else max(worst, tilt)
    return worst


def beam_at(attitudes: list, t_s: float) -> tuple[float, float, float] | None:
    """The rangefinder's beam (north-east-down) by the ATTITUDE of ``attitudes`` stamped nearest
    vehicle time ``t_s``; None when there is none or its angles are not finite."""
    if not attitudes:
        return None
    att = min(attitudes, key=lambda a: abs(a.time_boot_ms / 1000.0 - t_s))
    angles = (att.roll, att.pitch, att.yaw)
    return beam_direction(*angles) if all(math.isfinite(x) for x in angles) else None


class Lander:
    """Wires a link, the legs and the settings to a :class:`Machine`."""

    def __init__(
        self,
        link: Link,
        cfg: Config,
        preset: tuple[float, float],
        legs=None,
        record: IO[str] | None = None,
        next_preset: tuple[float, float] | None = None,
        uphill_angle_deg: float | None = None,
        slope_deg: float | None = None,
        slope_estimate: SlopeEstimate | None = None,
        slope_bound_deg: float | None = None,
    ) -> None:
        self.link = link
        #: the slope measured before the landing and the bound the landing's slope must keep to it
        #: (CHECKS refuses outside it); written first to the record, points and all
        self.slope_estimate = slope_estimate
        self.slope_bound_deg = slope_bound_deg
        if record is not None and slope_estimate is not None:
            entry = {
                "slope_estimate": slope_estimate.record(),
                "bound_deg": slope_bound_deg,
                "slope_deg": slope_deg,
            }
            record.write(json.dumps(entry) + "\n")
        link.heartbeats_missed = cfg["link.heartbeats_missed"]  # the link's loss rule, from the settings
        self.cfg = cfg
        self.legs = legs
        self.act = MavActions(link, cfg, legs)
        self.ctx = Context(
            cfg=cfg,
            act=self.act,
            preset=preset,
            next_preset=next_preset,
            uphill_angle_deg=uphill_angle_deg,
            slope_deg=slope_deg,
        )
        self.machine = Machine(self.ctx, record)
        self.detector = ImpactDetector(cfg["reflex.impact_threshold_mps2"])
        self.takeoff_request = False
        self._last_t = -1.0
        if legs is not None:  # the legs' timeouts run on vehicle time, like the machine's
            legs.set_clock(link.clock.now)
            legs.silence_timeout = cfg["legs.board_silent_s"]
        #: the board this landing drives, also while it is disconnected (``self.legs`` is None then)
        self.board = legs
        self._reconnect_tried = -math.inf
        if legs is not None and not legs.connected:  # it failed in an earlier landing
            self.legs = None
            self.act.legs = None
        self.start_preset = preset
        self.start_angle_deg = uphill_angle_deg
        self.switch = PresetSwitch(cfg, link.last.get("RC_CHANNELS"))
        self._legs_t: float | None = None
        #: RAW_IMU messages already given to the detector (the count of :meth:`Link.since`)
        self._imu_seen = link.received.get("RAW_IMU", 0)

    def inputs(self) -> Inputs:
        """The snapshot the machine steps on."""
        ln, cfg = self.link, self.cfg
        t = ln.clock.now()
        hb = ln.last.get("HEARTBEAT")
        mode = MODE_NAMES.get(hb.custom_mode, f"number {hb.custom_mode}") if hb else "unknown"
        armed = bool(hb and hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        ds = ln.last.get("DISTANCE_SENSOR")
        range_m, range_ok = None, False
        if ds is not None and ds.orientation == mavlink.MAV_SENSOR_ROTATION_PITCH_270:
            range_m = ds.current_distance / 100.0
            fresh = ln.age(ds.time_boot_ms / 1000.0) <= cfg["range.max_age_s"]
            inside = ds.min_distance <= ds.current_distance <= ds.max_distance
            q = getattr(ds, "signal_quality", 0)  # a MAVLink 1 link has no quality: unknown
            quality = q != 1 and (q == 0 or q >= cfg["range.min_quality"])
            range_ok = fresh and inside and quality
        imu = ln.last.get("RAW_IMU")
        accel = math.dist((0, 0, 0), raw_imu_accel(imu)) if imu else 9.80665
        pos = ln.last.get("LOCAL_POSITION_NED")
        speed = position = climb = None
        if pos is not None and ln.age(pos.time_boot_ms / 1000.0) <= cfg["settle.velocity_max_age_s"]:
            speed = math.sqrt(pos.vx * pos.vx + pos.vy * pos.vy + pos.vz * pos.vz)
            position = (pos.x, pos.y, pos.z)
            climb = -pos.vz
            if not (math.isfinite(speed) and all(math.isfinite(v) for v in position)):
                speed = position = climb = None
        tilt = beam = None
        if ds is not None:  # TAKEOFF's clear height, SETTLED's "in the air" and "down"
            # the body's tilt at the reading's own moment: the beam looks along the body, and a
            # newer attitude says nothing of an older reading (found by the soak under link noise)
            t_ds = ds.time_boot_ms / 1000.0
            near = ln.near("ATTITUDE", t_ds, cfg["takeoff.attitude_window_s"])
            tilt = tilt_at(near)
            beam = beam_at(near, t_ds)
        gp = ln.last.get("GLOBAL_POSITION_INT")
        above_home = None
        if gp is not None and ln.age(gp.time_boot_ms / 1000.0) <= cfg["settle.velocity_max_age_s"]:
            above_home = gp.relative_alt / 1000.0
        att = ln.last.get("ATTITUDE")
        heading = math.degrees(att.yaw) % 360.0 if att is not None and math.isfinite(att.yaw) else None
        op = self.act.leg_op
        legs_fault = None if self.legs is not None else "no leg board connected"
        legs_fault = self.ctx.marks.get("legs_error") or legs_fault
        legs_fault = self.act.leg_error or legs_fault
        legs_ready = False
        if op is not None:
            if op.error is not None:
                legs_fault = str(op.error)
            legs_ready = op.done and op.error is None and not self.act.legs_busy
        status = getattr(self.legs, "status", None)
        uphill = downhill = ()
        if status is not None:
            uphill = tuple(status.legs[i].angle_deg for i in self.legs.pairs.uphill)
            downhill = tuple(status.legs[i].angle_deg for i in self.legs.pairs.downhill)
        state = ln.script_state if ln.script_present else None
        return Inputs(
            t=t,
            link_ok=not ln.lost,
            link_lost_why=ln.lost_why or "",
            mode=mode,
            armed=armed,
            estop=state == SCRIPT_ESTOP,
            range_m=range_m,
            range_ok=range_ok,
            range_t=ds.time_boot_ms / 1000.0 if ds is not None else None,
            script_present=ln.script_present,
            script_state=state if state is not None else ScriptState.IDLE,
            script_version=ln.info.script_version if ln.info is not None else None,
            legs_ready=legs_ready,
            legs_fault=legs_fault,
            uphill_angles_deg=uphill,
            downhill_angles_deg=downhill,
            accel_mps2=accel,
            speed_mps=speed,
            climb_mps=climb,
            position_m=position,
            tilt_deg=tilt,
            heading_deg=heading,
            beam_ned=beam,
            above_home_m=above_home,
            impact=self.detector.impact is not None,
            takeoff_request=self.takeoff_request,
            slope_measured=self.slope_estimate,
            slope_bound_deg=self.slope_bound_deg,
        )

    def poll(self) -> str:
        """Read everything waiting, step the machine if vehicle time moved (or the link is lost).

        Every IMU sample received since the last poll reaches the impact detector, so the
        detector does not depend on how often the loop wakes. The snapshot is built only when the
        machine steps: a wake with nothing newer from the autopilot costs only the reads."""
        link = self.link
        link.poll()
        msgs, self._imu_seen = link.since("RAW_IMU", self._imu_seen)
        for msg in msgs:
            self.detector.feed_msg(msg)
        if self.legs is not None:
            t = link.clock.now()
            if self._legs_t is not None and t - self._legs_t > self.cfg["legs.board_silent_s"]:
                # the autopilot's clock jumped (it stood still while the link was lost): the
                # board was not watched in between, which says nothing about the board
                self.legs.unobserved(t - self._legs_t)
            self._legs_t = t
            try:
                self.legs.poll()
            except Exception as exc:  # a board that vanished is a leg failure, not a crash
                self.act.leg_op = None
                self.act.legs = None
                with contextlib.suppress(Exception):
                    self.legs.close()
                self.legs = None
                self.ctx.marks["legs_error"] = str(exc)
            self.act.advance()
        else:
            self._legs_back()
        self._pilot_switch()
        if link.clock.now() > self._last_t or link.lost:
            inp = self.inputs()
            self._last_t = inp.t
            before = self.machine.name
            self.machine.step(inp)
            if self.machine.name == "CUT" and before != "CUT":
                self.detector.arm_after_cut(inp.t)
        return self.machine.name

    def _legs_back(self) -> None:
        """Reconnect a board that failed once its port is back, between landings only
        (:data:`RECONNECT_IN`, or before this landing starts), at most every ``legs.reconnect_s``."""
        board = self.board
        if board is None or (self.machine._started and self.machine.name not in RECONNECT_IN):
            return
        now = self.link.monotonic()
        if now - self._reconnect_tried < self.cfg["legs.reconnect_s"]:
            return
        self._reconnect_tried = now
        if not os.path.exists(board.port):  # a dangling link: the board is not back yet
            return
        board.set_clock(time.monotonic)  # the handshake waits in local time, not on the autopilot's
        try:
            board.reconnect(HANDSHAKE_S)
        except (LegBoardError, OSError) as exc:
            board.close()
            self.ctx.marks["legs_error"] = f"leg board not back: {exc}"
            return
        finally:
            board.set_clock(self.link.clock.now)
        self.legs = self.act.legs = board
        self.act.leg_op, self.act.leg_error = None, None
        self.ctx.marks.pop("legs_error", None)
        self._legs_t = None
        self.act.statustext("SL leg board reconnected")

    def _pilot_switch(self) -> bool:
        """Apply a change of the pilot's preset switch (see :mod:`pilot_switch`); True when the
        legs were given another preset."""
        changed, sel = self.switch.update(self.link.last.get("RC_CHANNELS"))
        if not changed:
            return False
        if sel is None:
            preset, angle, label = self.start_preset, self.start_angle_deg, "landing's preset"
        else:
            preset, angle, label = (
                (sel.tau_up_nm, sel.tau_down_nm),
                sel.angle_up_deg,
                f"pilot preset {sel.name}",
            )
        name = self.machine.name if self.machine._started else "PRESET"
        what = f"{label} {preset[0]:.2f}/{preset[1]:.2f} N*m" + ("" if angle is None else f" {angle:g} deg")
        if name not in APPLY_IN:
            self.act.statustext(f"SL {what} ignored in {name}"[:50])
            return False
        refused = self.act.check_preset(*preset)
        if refused is not None:
            self.act.statustext(f"SL {what} refused: {refused}"[:50])
            return False
        self.ctx.preset = preset
        self.ctx.uphill_angle_deg = angle  # CHECKS holds the legs to it, as to the table's
        if name == "READY":
            self.ctx.next_preset = preset
        self.act.set_legs(*preset, angle)
        self.act.statustext(f"SL {what}"[:50])
        if self.machine._started and name in WAIT_AGAIN:
            inp = self.inputs()
            if name == "DESCEND":  # stop the descent now, not after GUID_TIMEOUT
                self.act._last_descent = -1.0
                self.act.descend(0.0)
            self.machine.transition("LEGS_WAIT", what, inp)
        return True

    def interrupt(self, count: int) -> bool:
        """The pilot's interrupt (Ctrl-C, SIGTERM) number ``count``, in the state the landing is
        in (docs/failsafes.md, "Interrupting a landing"); True when the landing loop should end.

        - Ended (LANDED, READY, ABORTED, ESTOP): nothing to do.
        - On the roof with the motors held (CUT, REVERSE, SETTLED): the first interrupt lets the
          landing finish to its confirmed disarm (releasing the script on a roof is what the
          landing exists to avoid); a second one ends the loop and leaves the vehicle to the
          script, which disarms it once still when the companion falls silent.
        - Anywhere else (before contact, in the air, in the take-off): the landing is aborted
          (the autopilot holds position in LOITER) and the loop ends once the autopilot says
          LOITER, or after a few seconds."""
        name = self.machine.name if self.machine._started else None
        if name in ENDINGS:
            return True
        inp = self.inputs()
        if name in ("CUT", "REVERSE", "SETTLED") or self.machine.held_on_the_roof(inp):
            if count == 1:
                self.act.statustext("SL interrupt: finishing the landing")
                return False
            self.act.statustext("SL interrupt: left to the on-board script")
            return True
        if name is not None:
            self.machine.transition("ABORTED", "interrupted by the pilot", inp)
        end = time.monotonic() + INTERRUPT_WAIT_S
        while time.monotonic() < end:
            self.poll()
            hb = self.link.last.get("HEARTBEAT")
            armed = hb is not None and hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
            if hb is not None and (not armed or MODES.get("LOITER") == hb.custom_mode):
                break
            time.sleep(0.01)
        return True

    def _ended(self, name: str) -> str:
        """The run ends in ``name``: an abort still climbing before LOITER (``Aborted.rising``)
        asks LOITER now, so the vehicle is never left on a GUIDED setpoint nobody renews."""
        if name == "ABORTED" and Aborted.rising(self.ctx):
            Aborted.ask_loiter(self.ctx, self.inputs())
        return name

    def abort_settling(self) -> bool:
        """Whether the landing is ABORTED but the abort still holds the reflex (until the vehicle
        climbs or holds) or rises before LOITER: not over yet, as the script may still cut
        (ABORTED -> CUT, "landing on"); :meth:`run` goes on polling then, for at most
        :data:`ABORT_SETTLE_S`."""
        if self.machine.name != "ABORTED":
            return False
        return bool(self.ctx.marks.get("abort_pending") or Aborted.rising(self.ctx))

    def run(
        self,
        timeout_s: float,
        sleep: Callable[[float], None] | None = None,
        until: tuple[str, ...] = ENDINGS,
        interrupts: Callable[[], int] | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> str:
        """Poll until an ending state (or ``timeout_s`` local seconds: then abort); returns the state.
        ``stop`` ends the run early, the machine left as it is: a supervisor's own end (a test's
        bound on a hold that has no end of its own), checked after each poll.
        Between polls it waits for the link or the leg board to have bytes (at most
        ``POLL_WAIT_S``), or calls ``sleep`` when one is given (tests). Polls are at least
        ``link.poll_period_s`` of vehicle time apart: the IMU, range and position frames of one
        autopilot cycle arrive as separate datagrams, and one wake-up for all of them is most of
        the CPU saved. On a real vehicle that is the same in local time; a simulated one running
        faster than real time is woken for that much faster (a lock-stepped simulator waits for
        the loop, and would otherwise be held to about five times real time)."""
        t0 = self.link.monotonic()
        period = self.cfg["link.poll_period_s"]
        rate = 1.0  # vehicle seconds per local second, smoothed; never taken below real time
        last_w, last_v = time.monotonic(), self.link.clock.now()
        handled = 0
        aborted_at = None
        while True:
            started = time.monotonic()
            name = self.poll()
            if self.machine._started and name in until:
                pending = self.abort_settling()
                aborted_at = aborted_at if aborted_at is not None else time.monotonic()
                if not pending or time.monotonic() - aborted_at > ABORT_SETTLE_S:
                    return self._ended(name)
            else:
                aborted_at = None
            if stop is not None and stop():
                return name
            if interrupts is not None and interrupts() > handled:
                handled = interrupts()
                if self.interrupt(handled):
                    return self._ended(self.machine.name) if self.machine._started else "ABORTED"
            if self.link.monotonic() - t0 > timeout_s:
                self.machine.transition(
                    "ABORTED", f"landing not finished within {timeout_s:g} s", self.inputs()
                )
                return self.machine.name  # SETTLED when the vehicle is held on the roof
            if sleep is not None:
                sleep(0.001)
            else:
                v = self.link.clock.now()
                if started > last_w:
                    r = (v - last_v) / (started - last_w)  # a jump after a gap is not a speed
                    rate += RATE_GAIN * (min(max(1.0, r), MAX_RATE) - rate)
                last_w, last_v = started, v
                rest = period / rate - (time.monotonic() - started)
                if rest > 0:
                    time.sleep(rest)  # a rate limit, not a synchronisation: the wait below follows
                # the autopilot's link only: a wait on the leg board's tty can be held by the
                # kernel for seconds on a loaded machine (LegBoard._read); its bytes are read
                # within POLL_WAIT_S anyway
                self.link.wait_readable(POLL_WAIT_S)
