"""One leg: its state machine, the clamp's current loop and the protections, once per tick.

The clamp. A lead screw this fine self-locks, and its nut is moved by a motor whose rotor,
seen through 1:298 and the screw, is heavy against the Belleville stack's spring: driven as a
torque source up to the target, the rotor would overrun the target force by tens of newtons.
So the firmware drives the nut at a set voltage (full speed from loose, gently for a small
step), watches the motor current (the load current once the rotor has accelerated), brakes
the motor just before the current reaches the target (the rotor stops within milliseconds,
the screw holds), then holds the stall current on the target with a PI loop: the screw moves
on only if the clamping is below the target, so the clamping ends where the target says.

Protections (docs/leg-protocol.md, fault codes): over-current, a drive that does not turn
(STUCK) or turns without current (SENSE), a nut past its range (TRAVEL), a motion that takes
too long (TIMEOUT). Every fault brakes the motor at once; only LOOSEN clears it.
"""

from legfw.compat import const, wire

_IDLE = const(0)
_RUN = const(1)  # driving the nut forward at the run voltage
_BRAKE = const(2)  # motor braked: the rotor stops, the screw holds
_HOLD = const(3)  # stall current held on the target
_BACK = const(4)  # driving back to the back stop
_MOVE_STOP = const(5)  # moving the rest stop (POSITIONING)
_PROBE = const(6)  # power-up: is the nut at its back stop?

UNKNOWN = const(1 << 30)  # "held" after power-up: the clamping is not known
_DRIVEN = (wire.TIGHTENING, wire.HOLDING, wire.LOOSENING, wire.POSITIONING)


class Leg:
    """The firmware's view of one leg; :meth:`tick` reads the HAL and drives the motor."""

    def __init__(self, index: int, cfg, hal) -> None:
        self.index = index
        self.cfg = cfg
        self.hal = hal
        self.state = wire.STOPPED
        self.fault = wire.FAULT_NONE
        self.phase = _PROBE
        self.target_ua = 0
        self.held_ua = UNKNOWN  # highest target since the nut was last at its back stop
        self.pending_ua = -1  # target to tighten to once loosened (0: only loosen), -1 none
        self.goal_cdeg = -1  # SET_ANGLE goal
        self.state_ms = 0
        self.phase_ms = 0
        self.settled_ms = 0
        self.still_ms = 0
        self.sense_ms = 0
        self.v_mv = 0
        self.run_mv = 0
        self.integral_uv = 0
        self.creep_ms = 0
        self.creep_count = 0
        self.reached_ticks = 0
        self.reruns = 0
        self.i_raw = 0
        self.i_filt = 0
        self.count = hal.encoder(index)
        self.moved = False
        self.count0 = self.count  # encoder count at the back stop
        self.known = False  # whether count0 is the back stop
        self.from_loose = False
        self.angle_cdeg = hal.angle_cdeg(index)
        self.stop_cdeg = wire.MAX_ANGLE_CDEG
        if cfg.angle_stop:
            hal.rest_stop(index, self.stop_cdeg)

    # ---- commands -------------------------------------------------------------------
    def set_friction(self, target_ma: int):
        """Clamp to a current target (0 = loosen); the NAK code if refused, else None."""
        if self.state == wire.FAULT:
            return wire.NAK_FAULTED
        if target_ma == 0:
            self.loosen()
            return None
        target = target_ma * 1000
        st = self.state
        if st == wire.LOOSENING or st == wire.POSITIONING or self.phase == _PROBE:
            self.pending_ua = target
        elif st == wire.LOOSE:
            self._tighten(target, True)
        elif target == self.target_ua and st != wire.STOPPED:
            pass  # a repeated command does not restart the motion
        elif st == wire.STOPPED and target == self.held_ua:
            self.target_ua = target  # the screw still holds it: take the hold up again
            self._enter(wire.TIGHTENING, _HOLD)
        elif target >= self.held_ua and self.held_ua != UNKNOWN:
            self._tighten(target, False)
        else:  # lower than held (or not known): the screw self-locks, so loosen first
            self.pending_ua = target
            self._enter(wire.LOOSENING, _BACK)
        return None

    def loosen(self) -> None:
        self.goal_cdeg = -1
        self.fault = wire.FAULT_NONE
        if self.phase == _PROBE:
            self.pending_ua = 0  # loosen once the power-up probe has ended
            return
        self.pending_ua = -1
        if self.state == wire.LOOSE:
            return
        if self.state != wire.LOOSENING:
            self._enter(wire.LOOSENING, _BACK)

    def set_angle(self, cdeg: int):
        if self.state == wire.FAULT:
            return wire.NAK_FAULTED
        self.goal_cdeg = cdeg
        self.pending_ua = -1
        if self.state != wire.POSITIONING:
            if self.state == wire.LOOSE:
                self._enter(wire.POSITIONING, _MOVE_STOP)
            else:
                self._enter(wire.POSITIONING, _BACK)
        return None

    def stop(self) -> None:
        if self.state != wire.FAULT:
            self.pending_ua = -1
            self._enter(wire.STOPPED, _IDLE)
            self.v_mv = 0
            self.hal.drive(self.index, 0)  # at once, not at the next tick

    # ---- reports --------------------------------------------------------------------
    def report(self) -> tuple:
        """``(state, fault, current_ma, target_ma, angle_cdeg)`` for STATUS."""
        ma = (self.i_filt + 500) // 1000
        ma = max(-wire.MAX_CURRENT_MA, min(wire.MAX_CURRENT_MA, ma))
        st = self.state
        target = self.target_ua // 1000 if st == wire.TIGHTENING or st == wire.HOLDING else 0
        angle = max(0, min(wire.MAX_ANGLE_CDEG, self.angle_cdeg))
        return (st, self.fault, ma, target, angle)

    def travel_x100(self) -> int:
        """Nut travel from the back stop, 1/100 mm (meaningful while :attr:`known`)."""
        return (self.count - self.count0) * 100 // self.cfg.counts_per_mm

    # ---- the tick -------------------------------------------------------------------
    def tick(self, dt: int) -> None:
        """One period of ``dt`` ms: measure, protect, step the state machine, drive."""
        cfg = self.cfg
        hal = self.hal
        leg = self.index
        i = hal.current_ua(leg)
        self.i_raw = i
        self.i_filt += (i - self.i_filt) >> cfg.filter_shift
        c = hal.encoder(leg)
        self.moved = c != self.count
        self.count = c
        self.angle_cdeg = hal.angle_cdeg(leg)
        self.state_ms += dt
        self.phase_ms += dt
        if (self.state in _DRIVEN or self.phase == _PROBE) and self._protect(dt):
            hal.drive(leg, 0)
            return
        phase = self.phase
        if phase == _RUN:
            v = self._run()
        elif phase == _BRAKE:
            v = self._brake()
        elif phase == _HOLD:
            v = self._hold(dt)
        elif phase == _BACK:
            v = self._back()
        elif phase == _MOVE_STOP:
            v = self._move_stop(dt)
        elif phase == _PROBE:
            v = self._probe()
        else:
            v = 0
        self.v_mv = v
        hal.drive(leg, v)

    def _protect(self, dt: int) -> bool:
        """Check the drive applied last tick against what it did; True if the leg faulted."""
        cfg = self.cfg
        i = self.i_raw
        v = self.v_mv
        if i > cfg.overcurrent_ma * 1000 or -i > cfg.overcurrent_ma * 1000:
            return self._fail(wire.FAULT_OVERCURRENT)
        driven = v >= cfg.sense_mv or -v >= cfg.sense_mv
        if driven and -cfg.sense_floor_ua < i < cfg.sense_floor_ua:
            self.sense_ms += dt
            if self.sense_ms >= cfg.sense_ms:
                return self._fail(wire.FAULT_SENSE)
        else:
            self.sense_ms = 0
        if self.phase == _RUN and (v >= cfg.stall_mv or -v >= cfg.stall_mv) and not self.moved:
            self.still_ms += dt
            if self.still_ms >= cfg.stall_ms:
                return self._fail(wire.FAULT_STUCK)
        else:
            self.still_ms = 0
        if self.phase == _RUN and self.known and self.travel_x100() > cfg.max_travel_mm_x100:
            return self._fail(wire.FAULT_TRAVEL)
        if self.state != wire.HOLDING and self.state_ms > cfg.motion_limit_ms:
            return self._fail(wire.FAULT_TIMEOUT)
        return False

    def _fail(self, code: int) -> bool:
        self._enter(wire.FAULT, _IDLE)
        self.fault = code
        if code == wire.FAULT_TRAVEL:
            self.known = False  # the encoder ran on without the nut: where the nut is, is lost
        self.pending_ua = -1
        self.v_mv = 0
        return True

    # ---- phases ---------------------------------------------------------------------
    def _enter(self, state: int, phase: int) -> None:
        self.state = state
        self.state_ms = 0
        self._phase(phase)
        self.settled_ms = 0
        self.from_loose = False

    def _phase(self, phase: int) -> None:
        self.phase = phase
        self.phase_ms = 0
        self.reached_ticks = 0
        self.still_ms = 0
        self.sense_ms = 0

    def _tighten(self, target: int, from_loose: bool, start_ua: int = -1) -> None:
        cfg = self.cfg
        self.reruns = 0
        if start_ua < 0:
            start_ua = 0 if from_loose or self.held_ua == UNKNOWN else self.held_ua
        self.target_ua = target
        self.held_ua = target
        self._enter(wire.TIGHTENING, _RUN)
        self.from_loose = from_loose
        # full speed for a long way, gently for a small step: the run voltage rises with the
        # error from the hold voltage (stall at the target) up to the drive limit
        hold_mv = cfg.r_mohm * target // 1000000
        error_ma = (target - start_ua) // 1000
        if from_loose or error_ma >= cfg.slow_ma:
            self.run_mv = cfg.v_max_mv
        else:
            self.run_mv = hold_mv + (cfg.v_max_mv - hold_mv) * max(1, error_ma) // cfg.slow_ma
        self.v_mv = 0

    def _run(self) -> int:
        cfg = self.cfg
        lead = cfg.lead_ua * self.v_mv // cfg.v_max_mv  # the faster the rotor, the further it runs on
        # in the clearance there is no clamp to reach: a current near a low target there is the
        # motor's own friction (and noise), so the nut runs on to the stack first
        free = self.known and self.moved and self.travel_x100() < cfg.clearance_mm_x100 * 97 // 100
        reached = self.phase_ms >= cfg.accel_ms and not free and self.i_filt >= self.target_ua - lead
        self.reached_ticks = self.reached_ticks + 1 if reached else 0
        if self.reached_ticks >= 2:  # two ticks running: one is as likely the sensor's noise
            early = cfg.clearance_mm_x100 * cfg.early_mm_pct // 100
            if self.from_loose and self.known and not self.moved and self.travel_x100() < early:
                self._fail(wire.FAULT_STUCK)  # stalled before the nut could reach the stack
                return 0
            self._phase(_BRAKE)
            return 0
        limit = self.run_mv
        if self.known and self.travel_x100() < cfg.clearance_mm_x100 * 9 // 10:
            limit = cfg.v_max_mv  # in the clearance: no force to approach gently yet
        return min(self.v_mv + cfg.soft_start_mv, limit)

    def _brake(self) -> int:
        # the braked rotor slows with the motor's mechanical time constant (about 20 ms); the
        # encoder, 3 counts a turn, cannot tell a slow rotor from a still one, so: a fixed time
        if self.phase_ms >= self.cfg.brake_ms:
            self._phase(_HOLD)
            self.integral_uv = 0
        return 0

    def _hold(self, dt: int) -> int:
        cfg = self.cfg
        if self.phase_ms == dt:  # the rotor has stopped: the current is the stall current from here
            self.i_filt = self.i_raw
            self.creep_ms = 0
            self.creep_count = self.count
        error = self.target_ua - self.i_filt
        self.creep_ms += dt
        if self.creep_ms >= cfg.creep_ms:  # a window: did the rotor creep on through it?
            crept = self.count - self.creep_count >= 2
            self.creep_ms = 0
            self.creep_count = self.count
            if crept and self.reruns < cfg.max_reruns:
                # the stall current is above the clamp's: short of it, run on to it (at least a few
                # mA's worth of speed: a creep converges, but over tens of seconds). A few times
                # only: near the motor's no-load current the creep is the clamp, and it settles
                reruns = self.reruns + 1
                self._tighten(self.target_ua, False, min(self.i_filt, self.target_ua - 5000))
                self.reruns = reruns
                return 0
        if self.moved:
            self.still_ms = 0
        else:
            self.still_ms += dt
        # integrate only on a rotor that has been still for a while: a creeping one (a count every
        # few hundred ms) draws less than its stall current, and an integral that made up for
        # that would drive the self-locking nut on past the target
        settling = self.state == wire.TIGHTENING and self.still_ms >= cfg.hold_still_ms
        if settling and (error > cfg.hold_deadband_ua or -error > cfg.hold_deadband_ua):
            # integrate only while settling and outside the noise: every upward wander of the
            # stall current above the clamp's breakaway advances the self-locking nut for good
            limit = cfg.hold_integral_mv * 1000
            self.integral_uv = max(-limit, min(limit, self.integral_uv + error * cfg.hold_gain_pct // 100))
        if -cfg.band_ua <= error <= cfg.band_ua:
            self.settled_ms += dt
            if self.state == wire.TIGHTENING and self.settled_ms >= cfg.settle_ms:
                self.state = wire.HOLDING
                self.state_ms = 0
        else:
            self.settled_ms = 0
        return cfg.r_mohm * self.target_ua // 1000000 + self.integral_uv // 1000

    def _back(self) -> int:
        cfg = self.cfg
        at_stop = self.phase_ms >= cfg.accel_ms and self.i_filt < -cfg.endstop_ma * 1000 and not self.moved
        if at_stop:
            if self.known and self.travel_x100() > cfg.stop_slack_mm_x100:
                self._fail(wire.FAULT_STUCK)  # stalled where the encoder says the nut is not at its stop
                return 0
            self._at_back_stop()
            return 0
        return max(self.v_mv - cfg.soft_start_mv, -cfg.v_max_mv)

    def _at_back_stop(self) -> None:
        self.count0 = self.count
        self.known = True
        self.held_ua = 0
        self.target_ua = 0
        if self.state == wire.POSITIONING:
            self._phase(_MOVE_STOP)
        elif self.pending_ua > 0:
            target = self.pending_ua
            self.pending_ua = -1
            self._tighten(target, True)
        else:
            self._enter(wire.LOOSE, _IDLE)

    def _move_stop(self, dt: int) -> int:
        cfg = self.cfg
        goal = self.goal_cdeg if self.goal_cdeg >= 0 else self.stop_cdeg
        step = cfg.stop_speed_cdeg_s * dt // 1000
        self.stop_cdeg += max(-step, min(step, goal - self.stop_cdeg))
        self.hal.rest_stop(self.index, self.stop_cdeg)
        if self.stop_cdeg == goal and -cfg.angle_band_cdeg <= self.angle_cdeg - goal <= cfg.angle_band_cdeg:
            self.goal_cdeg = -1
            pending = self.pending_ua
            self.pending_ua = -1
            self._enter(wire.LOOSE, _IDLE)
            if pending > 0:
                self._tighten(pending, True)
        return 0

    def _probe(self) -> int:
        """Power-up: pull the nut back gently. Still, with the stall current: it is at its
        back stop (LOOSE). It moved: it was clamped, by how much is unknown (STOPPED; the next
        clamp loosens it first). The pull is short and gentle, so a clamped leg stays clamped."""
        cfg = self.cfg
        if self.moved or self.phase_ms >= cfg.boot_probe_ms:
            if not self.moved and self.i_filt < -cfg.endstop_ma * 1000:
                self._at_back_stop()  # LOOSE, or on to a target asked for meanwhile
            else:
                self.count0 = self.count
                self._enter(wire.STOPPED, _IDLE)
                if self.pending_ua >= 0:  # a clamp or a loosening asked for meanwhile
                    self._enter(wire.LOOSENING, _BACK)
            return 0
        return max(self.v_mv - cfg.soft_start_mv, -cfg.boot_probe_mv)
