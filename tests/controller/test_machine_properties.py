"""The landing state machine under random event sequences (hypothesis stateful testing, on an
injected clock): whatever the vehicle, the link, the legs and the pilot do, and in whatever order,
the machine never raises, never commands reverse thrust or a disarm before an impact, never arms
the motor cut without a valid range, never loosens the legs on the ground, obeys the emergency
stop at once, and never stays in a waiting state for ever. After contact, while the vehicle is
armed and the script holds its motors, no state releases the script or aborts its reflex (the
tilted vehicle on the roof handed back of issue 21); LANDED is entered only with the HEARTBEAT
saying disarmed, and an armed HEARTBEAT there has the disarm asked again, never just kept."""

from __future__ import annotations

from dataclasses import replace

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule
from test_machine import Recorder  # the same recording stand-in for the actions

from slopelander.controller.config import load_config
from slopelander.controller.machine import STATES, Machine
from slopelander.controller.runner import ENDINGS
from slopelander.controller.states.base import Context, Inputs
from slopelander.controller.states.settled import AIR_MARGIN_M, DISARM_RETRY_S

CFG = load_config()
# states the machine may stay in while nothing changes: the autopilot flies, or it is over, or
# (SETTLED) the vehicle is armed on the ground with the motors held by the script and the disarm
# asked for until the HEARTBEAT says it was made: a landing does not end on a command sent
MAY_PERSIST = {"DESCEND", "ARMED", "TAKEOFF", "LANDED", "READY", "ABORTED", "ESTOP", "LINK_LOST", "SETTLED"}
AFTER_CONTACT = {"CUT", "REVERSE", "SETTLED", "LANDED"}
#: states only a vehicle that met the roof is in (CUT may still be falling: it counts once the
#: impact or the script's RVT/HOLD was seen)
ON_THE_ROOF = {"REVERSE", "SETTLED", "LANDED"}
MOTOR_STOPPERS = {"disarm", "disarm_on_ground", "reverse"}
#: the script's CUT, RVT and HOLD: it holds the motors stopped or reversed on the roof
SCRIPT_HOLDS = {11, 12, 13}
#: what would hand the motors of a vehicle on the roof to the autopilot's mixer
RELEASES = {"release", "reflex_abort"}


# readings at the thresholds that matter, and the ones a broken sensor gives
def script_holds(inp: Inputs) -> bool:
    """The script holds the motors as far as the companion can tell: it reports CUT, RVT or HOLD,
    or it fell silent after saying so with the range not reading the vehicle in the air (a dead
    script's overrides lapse, and above the cut height plus AIR_MARGIN_M the mixer flies it:
    docs/failsafes.md, SETTLED's silent row)."""
    if inp.script_state not in SCRIPT_HOLDS:
        return False
    if inp.script_present:
        return True
    r = inp.range_m
    in_air = (
        inp.range_ok
        and r is not None
        and r == r
        and r >= 0.0
        and r > CFG["reflex.cut_height_m"] + AIR_MARGIN_M
    )
    return not in_air


RANGES = [None, -1.0, 0.0, 0.29, 0.3, 0.31, 0.79, 0.8, 1.5, 1.51, 5.0, 50.0, float("nan"), float("inf")]


class LandingUnderRandomEvents(RuleBasedStateMachine):
    @initialize(start=st.sampled_from(["PRESET", "PRESET", "DESCEND", "ARMED", "LANDED", "TAKEOFF"]))
    def start(self, start: str) -> None:
        self.act = Recorder()
        ctx = Context(cfg=CFG, act=self.act, preset=(0.8, 1.5), next_preset=(0.6, 1.2))
        self.m = Machine(ctx, None, start)
        self.inp = Inputs(t=0.0, range_m=3.0, range_ok=True, legs_ready=False, script_state=0)
        self.impact_seen = start in ("LANDED", "TAKEOFF")  # it has landed before
        # on the roof since a contact state (or LANDED) and no take-off since
        self.on_roof = start == "LANDED"
        self.disarm_asked_at: float | None = None
        self.estop_seen = False
        self._step(0.02)

    def _step(self, dt: float, **changes) -> None:
        self.inp = replace(self.inp, t=self.inp.t + dt, **changes)
        if self.inp.impact or self.inp.script_state in (12, 13):
            self.impact_seen = True
        n, before, seen = len(self.act.calls), self.m.name, len(self.m.history)
        held = self.inp.script_state in (12, 13)  # the script's RVT or HOLD: it met the roof
        if before in ON_THE_ROOF or (before == "CUT" and (self.inp.impact or held)):
            self.on_roof = True
        if before == "LINK_LOST" and held:  # it came down while the link was out
            self.on_roof = True
        self.m.step(self.inp)  # must never raise
        new = self.act.calls[n:]
        names = [c[0] for c in new]
        visited = [h["to"] for h in self.m.history[seen:]]
        if self.m.name == "LANDED" and before != "LANDED":
            assert not self.inp.armed, f"LANDED entered from {before} with the vehicle armed"
        if self.on_roof and self.inp.armed and script_holds(self.inp) and not self.inp.estop:
            # after contact, armed, the script holding the motors: whatever the machine does (a
            # timeout, an abort, a link loss and back), nothing gives them to the mixer; only a
            # take-off asks the script for them (the script checks the tilt), and the pilot's
            # emergency stop releases everything (the stop itself keeps the motors off)
            assert not RELEASES & set(names), f"{names} from {before} via {visited}, armed, script holding"
            if "release_for_takeoff" in names:
                assert self.inp.takeoff_request, f"take-off release from {before} unasked"
        # the disarm is asked of whoever can make it: the script only in HOLD or STOP (an idle
        # script refuses it), the autopilot itself (unforced: only if landed) otherwise
        script_disarms = self.inp.script_present and self.inp.script_state in (1, 13)
        if ("disarm" in names and script_disarms) or "disarm_on_ground" in names:
            self.disarm_asked_at = self.inp.t
        if (
            self.m.name == "LANDED"
            and before == "LANDED"
            and self.inp.armed
            and self.inp.link_ok
            and not self.inp.takeoff_request
        ):
            # LANDED never keeps an armed vehicle as it is: the disarm is asked again (a lost
            # link's armed flag is stale and nothing sent arrives: asked once it is back)
            last = self.disarm_asked_at
            assert last is not None and self.inp.t - last <= DISARM_RETRY_S + 0.5, (
                f"LANDED kept armed since {last} (now {self.inp.t:.2f}) without a disarm asked"
            )
        if "TAKEOFF" in visited:
            self.on_roof = False
        if not self.impact_seen:
            stoppers = MOTOR_STOPPERS & set(names)
            if self.m.name == "LANDED" and before == "LANDED":
                # LANDED is entered only with the vehicle seen disarmed (on the ground: it
                # disarmed before the cut), and asks a re-armed one for the unforced disarm,
                # which ArduCopter refuses in the air (AP_Arming_Copter::disarm); found by
                # Hypothesis: DESCEND, disarmed, range 0, armed again
                stoppers -= {"disarm_on_ground"}
            assert not stoppers, f"{names} before any impact, in {self.m.name}"
        if "reflex_arm" in names:
            assert self.inp.range_ok and self.inp.range_m is not None, "cut armed without a valid range"
            assert self.inp.link_ok and self.inp.mode == "GUIDED"
        if "loosen_legs" in names:
            assert self.inp.range_ok and self.inp.range_m is not None, "legs loosened without a valid range"
            assert self.inp.range_m >= CFG["takeoff.clear_height_m"], "legs loosened on the ground"
        if self.inp.estop:
            assert self.m.name == "ESTOP"
            if self.estop_seen:
                assert set(names) <= {"statustext"}, f"commands {names} after the emergency stop"
            self.estop_seen = True

    # -- the world moves -------------------------------------------------------------------
    @rule(dt=st.floats(0.005, 0.5))
    def time_passes(self, dt: float) -> None:
        self._step(dt)

    @rule(
        dt=st.floats(0.005, 0.2),
        r=st.one_of(st.sampled_from(RANGES), st.floats(-1.0, 50.0)),
        ok=st.booleans(),
    )
    def range_reading(self, dt: float, r: float | None, ok: bool) -> None:
        self._step(dt, range_m=r, range_ok=ok)

    @rule(dt=st.floats(0.005, 0.2), s=st.sampled_from([0, 10, 11, 12, 13, 14, 99]))
    def script_reports(self, dt: float, s: int) -> None:
        self._step(dt, script_state=s)

    @rule(dt=st.floats(0.005, 0.2), present=st.booleans())
    def script_presence(self, dt: float, present: bool) -> None:
        self._step(dt, script_present=present)

    @rule(dt=st.floats(0.005, 0.2), a=st.floats(-50.0, 200.0), impact=st.booleans())
    def imu(self, dt: float, a: float, impact: bool) -> None:
        self._step(dt, accel_mps2=a, impact=impact)

    @rule(dt=st.floats(0.005, 0.2), ok=st.booleans())
    def link(self, dt: float, ok: bool) -> None:
        self._step(dt, link_ok=ok)

    @rule(dt=st.floats(0.005, 0.2), mode=st.sampled_from(["GUIDED", "LOITER", "LAND", "STABILIZE"]))
    def pilot_mode(self, dt: float, mode: str) -> None:
        self._step(dt, mode=mode)

    @rule(dt=st.floats(0.005, 0.2), armed=st.booleans())
    def arming(self, dt: float, armed: bool) -> None:
        self._step(dt, armed=armed)

    @rule(dt=st.floats(0.005, 0.2), ready=st.booleans(), fault=st.sampled_from([None, None, "board silent"]))
    def legs(self, dt: float, ready: bool, fault: str | None) -> None:
        self._step(dt, legs_ready=ready, legs_fault=fault)

    @rule(dt=st.floats(0.005, 0.2), req=st.booleans())
    def takeoff_request(self, dt: float, req: bool) -> None:
        self._step(dt, takeoff_request=req)

    @rule(dt=st.floats(0.005, 0.2), up=st.one_of(st.none(), st.floats(-1.0, 5.0)))
    def vehicle_height(self, dt: float, up: float | None) -> None:
        """LOCAL_POSITION_NED's height (None: none recent): the take-off's climb evidence."""
        self._step(dt, position_m=None if up is None else (0.0, 0.0, -up))

    @rule(dt=st.floats(0.005, 0.2))
    def landing_times_out(self, dt: float) -> None:
        """The runner's wall-clock timeout (Lander.run) aborts from any state but its endings."""
        if self.m.name in ENDINGS:
            return
        self.inp = replace(self.inp, t=self.inp.t + dt)
        n, before = len(self.act.calls), self.m.name
        self.m.transition("ABORTED", "landing not finished within 120 s", self.inp)
        names = [c[0] for c in self.act.calls[n:]]
        if self.on_roof and self.inp.armed and script_holds(self.inp):
            assert self.m.name == "SETTLED", f"timeout in {before} moved to {self.m.name}, armed on the roof"
            assert not RELEASES & set(names), f"{names} at the timeout in {before}, armed, script holding"
        self._step(0.0)

    @rule(dt=st.floats(0.005, 0.2), press=st.integers(0, 4))
    def emergency_stop(self, dt: float, press: int) -> None:
        self._step(dt, estop=press == 0)  # rarer than the rest: it ends the story

    # -- always ------------------------------------------------------------------------------
    @invariant()
    def a_known_state(self) -> None:
        assert self.m.name in STATES

    def teardown(self) -> None:
        """With nothing changing any more, no waiting state lasts for ever."""
        if not hasattr(self, "m"):
            return
        # each state that waits on a timeout ends within the longest wait the configuration
        # allows (the legs' ready timeout, the take-off's); waits may follow one another
        # (LEGS_WAIT's 30 s, then RESET's: found by Hypothesis), so the steps go on until the
        # state has not changed for longer than that, within a bound on the whole chain
        cfg = self.m.ctx.cfg
        longest = 10.0 + max(30.0, cfg["legs.ready_timeout_s"], cfg["settle.timeout_s"])
        elapsed = changed = 0.0
        seen = len(self.m.history)
        while elapsed < 6 * longest and elapsed - changed <= longest:
            self._step(0.1)
            elapsed += 0.1
            if len(self.m.history) != seen:
                seen, changed = len(self.m.history), elapsed
        assert self.m.name in MAY_PERSIST, (
            f"still in {self.m.name} after {elapsed - changed:.0f} s of unchanging inputs in it"
        )


LandingUnderRandomEvents.TestCase.settings = settings(
    max_examples=400, stateful_step_count=40, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
test_landing_under_random_events = LandingUnderRandomEvents.TestCase


def test_a_script_report_after_rvt_does_not_undo_the_contact() -> None:
    """Found by the property above (2026-11-26): the script's RVT seen, a timeout (SETTLED), then a
    CUT report (a script never goes back, but a reordered or stale report can say so) and a second
    timeout: the vehicle met the roof and is armed with the motors held, so it stays SETTLED."""
    state = LandingUnderRandomEvents()
    state.start(start="PRESET")
    state.script_reports(dt=0.125, s=12)
    state.landing_times_out(dt=0.125)
    state.script_reports(dt=0.125, s=11)
    state.landing_times_out(dt=0.125)
    assert state.m.name == "SETTLED"
    state.teardown()


# Sequences Hypothesis found in some runs and not in others (it also draws constants of the modules
# a run has loaded, so the suite's import order changes its examples): kept as plain tests.


def test_two_waits_in_a_row_each_end():
    """LEGS_WAIT's 30 s ready timeout, then (the script had met the roof) SETTLED and TAKEOFF's own
    15 s: each wait ends, though together they outlast one wait."""
    s = LandingUnderRandomEvents()
    s.start(start="PRESET")
    for _ in range(12):
        s.script_reports(dt=0.125, s=0)
    s.script_reports(dt=0.125, s=12)
    s.takeoff_request(dt=0.125, req=True)
    s.teardown()
    # the inputs frozen: a clear range (3 m) with no climb reported is not believed, the legs stay
    # clamped and the vehicle that never rose is asked to disarm where it is
    assert [h["to"] for h in s.m.history][-2:] == ["SETTLED", "TAKEOFF"]
    assert "loosen_legs" not in s.act.names() and "disarm_on_ground" in s.act.names()


def test_a_script_reversing_past_its_bound_is_not_released_before_a_take_off():
    """REVERSE outlasts the script's bound while the script still reports RVT; a take-off
    request follows. No release of the held motors (only the tilt-checked take-off release)."""
    s = LandingUnderRandomEvents()
    s.start(start="PRESET")
    s.script_reports(dt=0.005, s=0)
    s.script_reports(dt=0.005, s=0)
    s.imu(a=5.960464477539063e-08, dt=0.19875604310110628, impact=True)
    s.script_reports(dt=0.005, s=0)
    s.takeoff_request(dt=0.03650099953234336, req=False)
    s.legs(dt=0.07069460287171848, fault=None, ready=False)
    s.takeoff_request(dt=0.04395521341566689, req=False)
    s.takeoff_request(dt=0.1254270124221238, req=True)
    s.takeoff_request(dt=0.03439325250129231, req=True)
    s.takeoff_request(dt=0.1851058898755451, req=False)
    s.script_reports(dt=0.17895028932819845, s=11)
    s.takeoff_request(dt=0.009101307663329235, req=True)
    s.imu(a=44.32595070079144, dt=0.04308193380290513, impact=True)
    s.imu(a=9.319181340819697e-290, dt=0.14380486553537597, impact=False)
    s.script_reports(dt=0.03, s=12)
    s.imu(a=192.50311703431697, dt=0.1351199224258992, impact=True)
    s.legs(dt=0.06546432909838193, fault=None, ready=False)
    s.legs(dt=0.056270086546021746, fault=None, ready=False)
    s.imu(a=-2.225073858507203e-309, dt=0.08211368129390746, impact=True)
    s.imu(a=41.420440091781586, dt=0.1853642611893761, impact=True)
    s.takeoff_request(dt=0.12, req=True)
    s.legs(dt=0.06166850476486598, fault=None, ready=True)
    s.teardown()
    assert "script still reversing after its duration" in [h["reason"] for h in s.m.history]
