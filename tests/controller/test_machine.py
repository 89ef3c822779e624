"""The landing state machine on an injected clock: the nominal sequence and docs/failsafes.md row by row."""

from __future__ import annotations

import io
import json
import math
from dataclasses import replace

import pytest

from slopelander.controller.config import load_config
from slopelander.controller.machine import Machine
from slopelander.controller.states.base import Context, Inputs
from slopelander.controller.states.settled import DISARM_RETRY_S
from slopelander.controller.states.takeoff import HOLD_S


class Recorder:
    """Actions that record what the machine asked for (the MAVLink binding is tested in test_link)."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def __getattr__(self, name):
        def call(*args):
            self.calls.append((name, *args))

        return call

    def names(self) -> list[str]:
        return [c[0] for c in self.calls]


def make(start="PRESET"):
    act = Recorder()
    ctx = Context(cfg=load_config(), act=act, preset=(0.8, 1.5), next_preset=(0.6, 1.2))
    rec = io.StringIO()
    return Machine(ctx, rec, start), act, rec


OK = Inputs(t=0.0, range_m=5.0, range_ok=True, legs_ready=True)


def run_to(m: Machine, state: str, base: Inputs = OK, t0: float = 0.0) -> float:
    """Step the nominal flight until ``state``; returns the time."""
    t = t0
    rng = base.range_m
    script = 0
    climbed = 0.0
    for _ in range(2000):
        t += 0.02
        if m.name in ("DESCEND", "ARMED"):
            rng -= 0.5 * 0.02
        if m.name == "ARMED":
            script = max(script, 10)  # the script reports its reflex armed
        if m.name == "ARMED" and rng <= 0.3:
            script = 11
        if m.name == "CUT" and t - m.ctx.entered_at > 0.1:
            script = 12
        if m.name == "REVERSE" and t - m.ctx.entered_at > 0.3:
            script = 13
        inp = replace(base, t=t, range_m=rng, script_state=script)
        if m.name == "SETTLED" and "disarm_asked" in m.ctx.marks:
            inp = replace(inp, armed=False)  # the script's disarm, seen in the HEARTBEAT
        if m.name == "LANDED" and t - m.ctx.entered_at > 0.5:
            inp = replace(inp, armed=False, takeoff_request=True)
        if m.name in ("TAKEOFF",):
            rng += 0.02
            climbed += 0.02  # the vehicle's own height (LOCAL_POSITION_NED) rises with the range
            inp = replace(inp, range_m=rng, position_m=(0.0, 0.0, -climbed))
        if m.step(inp) == state:
            return t
    raise AssertionError(f"never reached {state}; at {m.name}")


def test_a_preset_the_legs_cannot_take_is_refused_before_the_descent():
    m, act, _ = make()

    def check_preset(up, down):
        act.calls.append(("check_preset", up, down))
        return "leg 2: 1.5 N·m is outside the calibrated range 0–1.2 N·m"

    act.check_preset = check_preset
    assert m.step(OK) == "ABORTED"
    assert m.history[-1]["reason"].startswith("PRESET refused: leg 2: 1.5 N·m is outside")
    assert "set_legs" not in act.names() and "descend" not in act.names()


def test_without_an_angle_actuator_the_pilot_is_told_and_a_wrong_angle_refused():
    m, act, _ = make()
    m.ctx.uphill_angle_deg = 25.7
    act.can_set_angle = lambda: False
    at_stop = replace(OK, uphill_angles_deg=(37.5, 37.5))
    assert m.step(at_stop) == "ABORTED"
    assert ("statustext", "SL set uphill legs to 25.7 deg by hand") in act.calls
    assert ("set_legs", 0.8, 1.5) in act.calls  # the torques still go to the board
    assert m.history[-1]["reason"] == "check failed: uphill legs at 37.5 deg, preset needs 25.7 deg"
    m2, act2, _ = make()
    m2.ctx.uphill_angle_deg = 25.7
    act2.can_set_angle = lambda: False
    set_by_hand = replace(OK, uphill_angles_deg=(26.5, 24.9))  # within legs.angle_tolerance_deg
    assert m2.step(set_by_hand) == "DESCEND"
    m3, _, _ = make()
    m3.ctx.uphill_angle_deg = 25.7
    assert m3.step(OK) == "ABORTED"  # no report of the angles: refused, not assumed
    assert m3.history[-1]["reason"] == "check failed: uphill leg angles not reported"


def test_with_an_angle_actuator_the_preset_sets_the_angle():
    m, act, _ = make()
    m.ctx.uphill_angle_deg = 25.7
    act.can_set_angle = lambda: True
    assert m.step(replace(OK, uphill_angles_deg=(25.6, 25.8))) == "DESCEND"
    assert ("set_legs", 0.8, 1.5, 25.7) in act.calls
    assert not any(c[0] == "statustext" and "by hand" in c[1] for c in act.calls)


def test_nominal_sequence_records_every_transition():
    m, act, rec = make()
    run_to(m, "LANDED")
    run_to(m, "READY", t0=100.0)
    seq = [h["to"] for h in m.history]
    assert seq == [
        "PRESET",
        "LEGS_WAIT",
        "CHECKS",
        "DESCEND",
        "ARMED",
        "CUT",
        "REVERSE",
        "SETTLED",
        "LANDED",
        "TAKEOFF",
        "RESET",
        "READY",
    ]
    lines = [json.loads(x) for x in rec.getvalue().splitlines()]
    assert lines == m.history
    names = act.names()
    assert [c for c in act.calls if c[0] != "statustext"][:2] == [
        ("check_preset", 0.8, 1.5),
        ("set_legs", 0.8, 1.5),
    ]
    assert "descend" in names and names.count("reflex_arm") >= 2  # armed and refreshed
    assert names.index("disarm") > names.index("reflex_arm")
    assert ("set_legs", 0.6, 1.2) in act.calls and names.index("loosen_legs") < len(names) - 1
    assert ("set_legs", 0.6, 1.2) in act.calls[names.index("loosen_legs") :]  # next preset after loosening
    assert any(c[0] == "statustext" and c[1].startswith("SL ARMED") for c in act.calls)


def test_legs_not_ready_in_time_aborts_before_descent():
    m, act, _ = make()
    limit = m.ctx.cfg["legs.ready_timeout_s"]
    for i in range(int(limit / 0.02) + 10):
        m.step(replace(OK, t=i * 0.02, legs_ready=False))
    assert m.name == "ABORTED" and "descend" not in act.names()


@pytest.mark.parametrize(
    ("change", "why"),
    [
        ({"script_present": False}, "script"),
        ({"script_version": None}, "did not report its version"),
        ({"script_version": 9.0}, "v9, v10 needed"),  # contract 10 scales a lapse's band with speed
        ({"range_ok": False}, "rangefinder"),
        ({"mode": "LOITER"}, "GUIDED"),
        ({"armed": False}, "armed"),
    ],
)
def test_checks_refuse(change, why):
    m, act, _ = make()
    base = replace(OK, **change)
    m.step(replace(base, t=0.0))
    m.step(replace(base, t=0.02))
    assert m.name == "ABORTED" and why in m.history[-1]["reason"]
    assert "descend" not in act.names()


# failsafes.md, one row at a time: (state, failure) -> (next state, what must have been sent; an
# abort from the descent asks LOITER after its 1 m rise)
ROWS = [
    ("DESCEND", {"link_ok": False}, "LINK_LOST", []),
    ("ARMED", {"link_ok": False}, "LINK_LOST", []),
    ("CUT", {"link_ok": False}, "LINK_LOST", []),
    ("DESCEND", {"range_ok": False}, "ABORTED", ["hold", "reflex_abort", "release", "hold", "set_mode"]),
    ("ARMED", {"range_ok": False}, "ABORTED", ["hold", "reflex_abort", "release", "hold", "set_mode"]),
    ("CUT", {"range_ok": False}, "CUT", []),
    (
        "ARMED",
        {"legs_fault": "board silent"},
        "ABORTED",
        ["hold", "reflex_abort", "release", "hold", "set_mode"],
    ),
    ("CUT", {"legs_fault": "board silent"}, "CUT", []),
    (
        "DESCEND",
        {"script_present": False},
        "ABORTED",
        ["hold", "reflex_abort", "release", "hold", "set_mode"],
    ),
    ("ARMED", {"mode": "LOITER"}, "ABORTED", ["reflex_abort", "release"]),
    ("DESCEND", {"estop": True}, "ESTOP", ["reflex_abort"]),
    ("REVERSE", {"estop": True}, "ESTOP", ["reflex_abort"]),
    ("LANDED", {"link_ok": False}, "LANDED", []),
    # the script cut between two steps: its CUT wins over a range below the sensor's minimum,
    # a leg fault or a script gap read in the same batch (aborting would release a falling vehicle)
    ("ARMED", {"range_ok": False, "script_state": 11}, "CUT", []),
    ("ARMED", {"legs_fault": "board silent", "script_state": 12}, "REVERSE", []),
    ("DESCEND", {"range_m": None, "script_state": 11}, "CUT", []),
]


@pytest.mark.parametrize(("state", "failure", "expect", "sent"), ROWS)
def test_failsafe_row(state, failure, expect, sent):
    m, act, _ = make()
    t = run_to(m, state)
    before = len(act.calls)
    fields = {
        "t": t + 0.02,
        "range_m": 0.2 if state != "DESCEND" else 3.0,
        "script_state": {"CUT": 11, "REVERSE": 12}.get(state, 0),
    }
    inp = replace(OK, **{**fields, **failure})
    m.step(inp)
    assert m.name == expect
    if expect == "ABORTED" and "set_mode" in sent:  # from the descent: LOITER after the rise
        rise_to_loiter(m, act, inp)
    new = [c[0] for c in act.calls[before:] if c[0] not in ("statustext", "descend")]
    assert new == sent
    if expect == "ABORTED" and "set_mode" in sent:
        assert ("set_mode", "LOITER") in act.calls


def rise_to_loiter(m, act, inp, rate_mps: float = 0.5, stops: bool = True) -> float:
    """Step an abort from the descent while the vehicle climbs at ``rate_mps`` (its position
    rising; once the hold setpoint is sent, at rest if ``stops``) until LOITER is asked; the
    height it rose (m). Fails past the rise's bound."""
    from slopelander.controller.states.aborted import RISE_M, RISE_MAX_S, STOP_MAX_S

    assert ("set_mode", "LOITER") not in act.calls, "LOITER asked before the rise"
    x, y, z = inp.position_m
    risen, rate, held = 0.0, rate_mps, None
    for k in range(1, round((RISE_MAX_S + STOP_MAX_S + 0.2) / 0.02)):
        risen += rate * 0.02
        m.step(replace(inp, t=inp.t + 0.02 * k, position_m=(x, y, z - risen), climb_mps=rate))
        if held is None and ("hold", 0.0) in act.calls:
            held, rate = risen, (0.0 if stops else rate)
        if ("set_mode", "LOITER") in act.calls:
            if rate_mps > 0.0:  # risen the full height, stopped by the hold setpoint first
                assert held is not None and held >= RISE_M - 1e-9, (held, risen)
            return risen
    raise AssertionError("no LOITER within the rise's bound")


# LANDED with the vehicle armed again (a pilot's arm, a late HEARTBEAT): the script accepts a
# disarm only in HOLD or STOP (docs/onboard-script.md) and went IDLE when the vehicle disarmed, so
# an IDLE (or absent) script is not asked: the companion's own unforced disarm goes, which
# ArduCopter accepts only with its land detector saying landed (docs/failsafes.md)
LANDED_ARMED_ROWS = [
    ({"script_state": 0}, ["disarm_on_ground"]),
    ({"script_state": 0, "script_present": False}, ["disarm_on_ground"]),
    ({"script_state": 13}, ["disarm"]),
    ({"script_state": 1}, ["disarm"]),
]


@pytest.mark.parametrize(("inputs", "sent"), LANDED_ARMED_ROWS)
def test_landed_armed_row(inputs, sent):
    m, act, _ = make()
    t = run_to(m, "LANDED")
    before = len(act.calls)
    t += DISARM_RETRY_S  # past the retry period of SETTLED's own last request
    for i in range(1, 4):  # 0.06 s: one request, the next only after DISARM_RETRY_S
        m.step(replace(OK, t=t + 0.02 * i, range_m=0.2, armed=True, **inputs))
    assert m.name == "LANDED"
    assert [c[0] for c in act.calls[before:] if c[0] != "statustext"] == sent


def test_an_abort_in_the_air_stops_the_descent_first_and_keeps_the_reflex_until_climbing():
    """ABORTED sends a climb setpoint before the mode change, and lets the reflex go only once the
    vehicle climbs or holds: a lost LOITER command no longer leaves the 0.5 m/s descent target
    running into the roof with the reflex disarmed (docs/failsafes.md)."""
    m, act, _ = make()
    t = run_to(m, "ARMED")
    before = len(act.calls)
    inp = replace(OK, t=t + 0.02, range_m=0.8, range_ok=False, script_state=10, climb_mps=-0.5)
    m.step(inp)
    assert m.name == "ABORTED"
    sent = [c for c in act.calls[before:] if c[0] != "statustext"]
    assert sent[0] == ("hold", 0.3) and "set_mode" not in act.names()  # LOITER after the rise
    # still descending: the reflex stays armed (not let go), the climb is re-sent
    for k in range(1, 20):
        m.step(replace(inp, t=inp.t + 0.02 * k))
    assert "reflex_abort" not in act.names() and m.ctx.marks["abort_pending"]
    assert ("descend", -0.5) in act.calls
    # the roof came anyway: the reflex cut it, and the landing goes on
    m2, act2, _ = make()
    t2 = run_to(m2, "ARMED")
    m2.step(replace(inp, t=t2 + 0.02))
    m2.step(replace(inp, t=t2 + 0.04, script_state=11))
    assert m2.name == "CUT" and "reflex_abort" not in act2.names()
    # climbing: after HOLDING_S the reflex is let go and the script released
    from slopelander.controller.states.aborted import HOLDING_S

    t3 = inp.t + 0.4
    for k in range(int(HOLDING_S / 0.02) + 3):
        m.step(replace(inp, t=t3 + 0.02 * k, climb_mps=0.2))
    assert act.names()[-2:] == ["reflex_abort", "release"] or {"reflex_abort", "release"} <= set(act.names())
    assert not m.ctx.marks["abort_pending"]


@pytest.mark.parametrize("state", ["DESCEND", "ARMED", "CUT"])
def test_an_abort_from_the_descent_climbs_before_loiter(state):
    """LOITER holds the height it is given: an abort close over the roof (a soak on ArduCopter left
    a vehicle hovering armed 0.17 m over it, its range stuck at 0.34 m) first climbs 1 m at
    0.5 m/s in GUIDED, holds, and LOITER is asked once the climb has stopped."""
    m, act, _ = make()
    t = run_to(m, state)
    inp = replace(OK, t=t + 0.02, range_m=0.34, script_state={"CUT": 11}.get(state, 10))
    m.transition("ABORTED", "test: abort low", inp)
    assert m.name == "ABORTED"
    assert ("hold", 0.3) in act.calls and "set_mode" not in act.names()
    rise_to_loiter(m, act, inp)
    assert ("descend", -0.5) in act.calls


def test_an_abort_from_the_descent_rises_within_its_bounds():
    """The rise ends in LOITER after RISE_MAX_S when the vehicle does not climb, at once when the
    position is lost, STOP_MAX_S after the hold setpoint when the climb does not stop, and is
    left alone (no LOITER) when the pilot or autopilot changes mode."""
    from slopelander.controller.states.aborted import RISE_MAX_S, STOP_MAX_S

    m, act, _ = make()
    inp = replace(OK, t=run_to(m, "ARMED") + 0.02, script_state=10)
    m.transition("ABORTED", "test", inp)
    assert rise_to_loiter(m, act, inp, rate_mps=0.0) == 0.0
    asked = next(c for c in m.history if c["to"] == "ABORTED")["t"]
    assert act.calls.count(("set_mode", "LOITER")) == 1
    assert m.ctx.marks["loiter_asks"][1] - asked == pytest.approx(RISE_MAX_S, abs=0.03)
    m, act, _ = make()
    inp = replace(OK, t=run_to(m, "ARMED") + 0.02, script_state=10)
    m.transition("ABORTED", "test", inp)
    m.step(replace(inp, t=inp.t + 0.02, position_m=None))
    assert ("set_mode", "LOITER") in act.calls
    m, act, _ = make()  # a climb that does not stop on the hold setpoint: LOITER after STOP_MAX_S
    inp = replace(OK, t=run_to(m, "ARMED") + 0.02, script_state=10)
    m.transition("ABORTED", "test", inp)
    assert rise_to_loiter(m, act, inp, stops=False) == pytest.approx(1.0 + 0.5 * STOP_MAX_S, abs=0.03)
    m, act, _ = make()
    inp = replace(OK, t=run_to(m, "ARMED") + 0.02, script_state=10)
    m.transition("ABORTED", "test", inp)
    for k in range(1, 300):
        m.step(replace(inp, t=inp.t + 0.02 * k, mode="ALT_HOLD"))
    assert "set_mode" not in act.names()


def test_an_abort_before_the_descent_asks_loiter_at_once():
    """From LEGS_WAIT (hovering at the approach height) LOITER is asked with the climb setpoint."""
    m, act, _ = make()
    m.step(replace(OK, t=0.02, legs_ready=False))
    assert m.name == "LEGS_WAIT"
    m.transition("ABORTED", "test", replace(OK, t=0.04, legs_ready=False))
    first = [c for c in act.calls if c[0] in ("hold", "set_mode")][:2]
    assert first == [("hold", 0.3), ("set_mode", "LOITER")]


def test_link_back_after_loss_aborts_to_loiter():
    m, act, _ = make()
    t = run_to(m, "DESCEND")
    m.step(replace(OK, t=t + 0.1, link_ok=False, link_lost_why="nothing heard for 1.60 s of local time"))
    assert m.name == "LINK_LOST"
    # the record says which of the link's rules fired
    assert m.history[-1]["reason"] == "link to the autopilot lost (nothing heard for 1.60 s of local time)"
    assert not any(c[0] == "statustext" for c in act.calls if c[1:] and "LINK_LOST" in str(c[1]))
    m.step(replace(OK, t=t + 2.0, range_m=2.0))
    assert m.name == "ABORTED" and ("set_mode", "LOITER") in act.calls


@pytest.mark.parametrize("lost_in", ["CUT", "REVERSE", "SETTLED"])
def test_link_back_after_contact_judges_rest_instead_of_releasing_the_script(lost_in):
    """The vehicle is on the roof and the script owns the motors: back to SETTLED, which disarms a
    vehicle at rest (or LANDED when the script's lapse already disarmed it); no release, no LOITER."""
    for armed_when_back, expect in ((True, "SETTLED"), (False, "LANDED")):
        m, act, _ = make()
        t = run_to(m, lost_in)
        script = 13 if lost_in != "CUT" else 11
        m.step(replace(OK, t=t + 0.02, range_m=0.2, script_state=script, impact=True, link_ok=False))
        assert m.name == "LINK_LOST"
        before = len(act.calls)
        back = replace(OK, t=t + 4.0, range_m=0.2, script_state=13, impact=True, armed=armed_when_back)
        m.step(back)
        assert m.name == expect, m.history[-2:]
        sent = [c[0] for c in act.calls[before:]]
        assert "release" not in sent and "set_mode" not in sent, sent
        if expect == "SETTLED":  # at rest: disarmed deliberately, as after any landing
            for i in range(1, 200):
                asked = "disarm_asked" in m.ctx.marks  # then the HEARTBEAT says disarmed
                m.step(replace(back, t=back.t + 0.02 * i, armed=not asked))
                if m.name != "SETTLED":
                    break
            assert m.name == "LANDED" and "disarm" in [c[0] for c in act.calls[before:]]


def test_false_cut_and_no_impact():
    m, _, _ = make()
    t = run_to(m, "CUT")
    m.step(replace(OK, t=t + 0.05, range_m=0.2, script_state=0))
    assert m.name == "ABORTED" and "false cut" in m.history[-1]["reason"]
    # the script's state still CUT past the companion's backstop (a stale announcement): the range
    # decides. High above the roof: aborted to the autopilot, which flies.
    m, _, _ = make()
    t = run_to(m, "CUT")
    m.step(replace(OK, t=t + 1.3, range_m=1.2, script_state=11))
    assert m.name == "CUT"  # within the script's own bound (0.35 s), its wait for a fall and the margin
    m.step(replace(OK, t=t + 1.4, range_m=1.2, script_state=11))
    assert m.name == "ABORTED" and "not near the roof" in m.history[-1]["reason"]
    # on the roof: the motors stay held and the landing is judged as it lies
    m, act, _ = make()
    t = run_to(m, "CUT")
    m.step(replace(OK, t=t + 1.4, range_m=0.2, script_state=11))
    assert m.name == "SETTLED" and "on the roof" in m.history[-1]["reason"]
    assert "release" not in act.names() and "reflex_abort" not in act.names()


def test_the_cut_backstop_follows_the_cut_height_and_the_descent_rate():
    """The script's missed-impact bound is the free fall from the cut height (0.35 s for 0.30 m at
    0.5 m/s), not a fixed 1 s: 4.9 m of free fall."""
    from slopelander.controller.script_contract import missed_impact_s

    assert missed_impact_s(0.30, 0.5) == pytest.approx(0.352, abs=0.002)
    assert missed_impact_s(1.0, 0.5) > missed_impact_s(0.3, 0.5)


def test_reset_waits_for_the_legs_to_loosen_before_the_next_preset():
    m, act, _ = make()
    run_to(m, "LANDED")
    t = run_to(m, "RESET", base=replace(OK, legs_ready=False), t0=100.0)
    for _ in range(50):
        t += 0.02
        m.step(replace(OK, t=t, legs_ready=False))
    assert m.name == "RESET" and ("set_legs", 0.6, 1.2) not in act.calls
    m.step(replace(OK, t=t + 0.02, legs_ready=True))
    assert m.name == "READY" and m.history[-1]["reason"].startswith("legs loosened")
    assert ("set_legs", 0.6, 1.2) in act.calls


def test_reset_gives_up_on_legs_that_never_report_loose():
    m, _, _ = make()
    run_to(m, "LANDED")
    t = run_to(m, "RESET", base=replace(OK, legs_ready=False), t0=100.0)
    timeout = m.ctx.cfg["legs.ready_timeout_s"]
    m.step(replace(OK, t=t + timeout - 0.1, legs_ready=False))
    assert m.name == "RESET"
    m.step(replace(OK, t=t + timeout + 0.1, legs_ready=False))
    # not ready for a next landing: handed to the autopilot's LOITER, not left hovering in GUIDED
    assert m.name == "READY" and "in time" in m.history[-1]["reason"]
    assert ("hold", 0.0) in m.ctx.act.calls and ("set_mode", "LOITER") in m.ctx.act.calls


def test_a_script_stuck_in_reverse_thrust_is_not_released_on_the_roof():
    """Past its bound the machine stops waiting for the script's reverse phase, without a
    release: the script refuses one from the cut on, and releasing the motors of a vehicle on
    the roof is what the landing avoids (found by Hypothesis, test_machine_properties)."""
    m, act, _ = make()
    t = run_to(m, "REVERSE")
    cfg = m.ctx.cfg
    limit = (cfg["reflex.reverse_max_ms"] + cfg["reflex.reverse_ramp_ms"]) / 1000.0 + 1.0
    m.step(replace(OK, t=t + limit - 0.1, range_m=0.2, script_state=12, speed_mps=0.1))
    assert m.name == "REVERSE"
    n = len(act.calls)
    m.step(replace(OK, t=t + limit + 0.1, range_m=0.2, script_state=12, speed_mps=0.1))
    assert m.name == "SETTLED" and "still reversing" in m.history[-1]["reason"]
    assert not {"release", "reflex_abort"} & {c[0] for c in act.calls[n:]}, act.calls[n:]


def test_a_vehicle_that_never_comes_still_is_disarmed_after_the_settle_timeout():
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    timeout = m.ctx.cfg["settle.timeout_s"]
    m.step(replace(OK, t=t + timeout - 0.1, range_m=0.2, script_state=13, accel_mps2=30.0))
    assert m.name == "SETTLED"
    m.step(replace(OK, t=t + timeout + 0.1, range_m=0.2, script_state=13, accel_mps2=30.0))
    assert m.name == "SETTLED" and "disarm" in [c[0] for c in act.calls]  # asked, not yet made
    m.step(replace(OK, t=t + timeout + 0.2, range_m=0.2, script_state=13, accel_mps2=30.0, armed=False))
    assert m.name == "LANDED" and "timeout" in m.history[-1]["reason"]


@pytest.mark.parametrize("bad", [None, -1.0, float("nan"), float("inf")])
def test_a_number_in_an_invalid_range_never_loosens_the_legs(bad):
    m, act, _ = make()
    run_to(m, "LANDED")
    t = 300.0
    m.step(replace(OK, t=t, range_m=0.1, armed=False))
    m.step(replace(OK, t=t + 0.1, range_m=5.0, range_ok=False, armed=False, takeoff_request=True))
    assert m.name == "TAKEOFF" and "loosen_legs" not in [c[0] for c in act.calls]
    m.step(replace(OK, t=t + 0.2, range_m=bad, range_ok=True, takeoff_request=True))
    assert m.name == "TAKEOFF" and "loosen_legs" not in [c[0] for c in act.calls]
    for i in range(30):  # a believed range above the clear height, held for 0.5 s
        if (
            m.step(replace(OK, t=t + 0.3 + 0.02 * i, range_m=1.0, takeoff_request=True, position_m=up(0.9)))
            != "TAKEOFF"
        ):
            break
    assert m.name == "RESET" and i * 0.02 >= HOLD_S - 1e-9


def test_reset_reports_legs_that_do_not_loosen():
    m, _, _ = make()
    run_to(m, "LANDED")
    run_to(m, "RESET", base=replace(OK, legs_ready=False), t0=100.0)
    m.step(replace(OK, t=300.0, legs_ready=False, legs_fault="leg 2: motor stalled"))
    assert m.name == "READY" and "did not loosen: leg 2: motor stalled" in m.history[-1]["reason"]
    assert ("set_mode", "LOITER") in m.ctx.act.calls


def test_reset_does_not_take_the_previous_presets_readiness_for_the_loosening():
    m, _, _ = make()
    run_to(m, "LANDED")
    run_to(m, "RESET", t0=100.0)  # legs_ready stays True in these inputs, as the preset's op was
    assert m.name == "RESET"


def test_reverse_thrust_lasts_its_minimum_then_ends_once_the_vehicle_is_still():
    m, act, _ = make()
    t = run_to(m, "REVERSE")
    cfg = m.ctx.cfg
    shortest, hold = cfg["reflex.reverse_thrust_ms"] / 1000.0, cfg["reflex.reverse_still_s"]
    at_rest = replace(OK, range_m=0.2, script_state=12, speed_mps=0.0)
    m.step(replace(at_rest, t=t + shortest - 0.05))
    assert m.name == "REVERSE"  # still from the start, but the minimum is not over
    n = len(act.calls)
    m.step(replace(at_rest, t=t + shortest + 0.01))
    assert m.name == "SETTLED" and "still under reverse thrust" in m.history[-1]["reason"]
    assert ("reflex_end_reverse",) in act.calls[n:]
    assert hold <= shortest  # the rest began at entry, so the hold was over by the minimum


def test_once_the_thrust_is_ended_no_refresh_puts_it_back_on():
    """After REVERSE ends the thrust, SETTLED's refreshes say duration 0 as well: a refresh with the
    full duration reaching the script before (or instead of) the end would keep the thrust on to its
    3 s bound (the link drops a pending command when a newer one with the same id is sent)."""
    m, act, _ = make()
    t = run_to(m, "REVERSE")
    shortest = m.ctx.cfg["reflex.reverse_thrust_ms"] / 1000.0
    at_rest = replace(OK, range_m=0.2, script_state=12, speed_mps=0.0)
    m.step(replace(at_rest, t=t + shortest + 0.01))
    assert m.name == "SETTLED"
    n = len(act.calls)
    for i in range(1, 60):  # the script still ramps (RVT), then holds (HOLD)
        m.step(replace(at_rest, t=t + shortest + 0.01 + 0.02 * i, script_state=12 if i < 40 else 13))
    sent = [c[0] for c in act.calls[n:]]
    assert "reflex_end_reverse" in sent and "reflex_refresh" not in sent, sent


def test_reverse_thrust_goes_on_while_the_vehicle_slides_until_the_scripts_bound():
    m, act, _ = make()
    t = run_to(m, "REVERSE")
    longest = m.ctx.cfg["reflex.reverse_max_ms"] / 1000.0
    sliding = replace(OK, range_m=0.2, script_state=12, speed_mps=0.4)
    for dt in (0.6, 1.0, 2.0, longest - 0.05):
        m.step(replace(sliding, t=t + dt))
        assert m.name == "REVERSE", dt
    # a slide that ends under the thrust: rest for the hold time ends it
    m.step(replace(sliding, t=t + longest - 0.04, speed_mps=0.01))
    assert m.name == "REVERSE"
    m.step(replace(sliding, t=t + longest - 0.03 + m.ctx.cfg["reflex.reverse_still_s"], speed_mps=0.01))
    assert m.name == "SETTLED" and "reflex_end_reverse" in act.names()


def slide_steps(m, t0: float, speed: float, base: Inputs, n: int = 20, dt: float = 0.05):
    """Steps of a vehicle moving ``speed`` m/s downhill (+x) from SETTLED's start on."""
    for i in range(1, n + 1):
        m.step(replace(base, t=t0 + dt * i, speed_mps=speed, position_m=(speed * dt * i, 0.0, 0.0)))


def test_the_scripts_bound_ends_reverse_thrust_and_a_slide_after_it_is_not_disarmed():
    m, act, _ = make()
    t = run_to(m, "REVERSE")
    longest = m.ctx.cfg["reflex.reverse_max_ms"] / 1000.0
    m.step(replace(OK, t=t + longest + 0.01, range_m=0.2, script_state=13, speed_mps=0.4))
    assert m.name == "SETTLED" and "ended by the script" in m.history[-1]["reason"]
    n = len(act.calls)
    slide_steps(m, t + longest + 0.01, 0.4, replace(OK, range_m=0.2, script_state=13))
    # sliding 0.4 m/s for 1 s: not disarmed, and not handed to the autopilot (no release, no LOITER)
    assert m.name == "SETTLED"
    sent = act.calls[n:]
    names = [c[0] for c in sent]
    assert "disarm" not in names and "release" not in names and "set_mode" not in names, names
    assert any(c[0] == "statustext" and "sliding at 0.40 m/s" in c[1] for c in sent), sent


def test_a_steady_slide_reading_one_g_is_never_called_still():
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    n = len(act.calls)
    # constant speed: no acceleration, so the accelerometer reads exactly 1 g
    slide = replace(OK, range_m=0.2, script_state=13, accel_mps2=9.80665)
    slide_steps(m, t, 0.5, slide, n=60)
    assert m.name == "SETTLED"
    assert "disarm" not in [c[0] for c in act.calls[n:]]


def test_one_fast_velocity_sample_is_not_a_slide():
    """After a link stall the impact's pivot once read as a 1.4 m/s slide 0.14 s after the cut:
    a slide is a displacement over vehicle time, and a vehicle that has not moved is disarmed."""
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    rest = replace(OK, range_m=0.2, script_state=13, speed_mps=0.0, position_m=(0.0, 0.0, 0.0))
    m.step(replace(rest, t=t + 0.02, speed_mps=1.4))
    for i in range(2, 80):
        m.step(replace(rest, t=t + 0.02 * i, armed="disarm" not in act.names()))
        if m.name != "SETTLED":
            break
    assert m.name == "LANDED", m.history[-2:]
    assert not any(c[0] == "statustext" and "sliding" in c[1] for c in act.calls)


def test_creeping_below_the_slide_speed_is_not_still_either():
    m, _, _ = make()
    t = run_to(m, "SETTLED")
    creep = replace(OK, range_m=0.2, script_state=13, speed_mps=0.1)  # between still and slide
    for dt in (0.5, 1.5, 3.0):
        m.step(replace(creep, t=t + dt))
        assert m.name == "SETTLED", dt
    m.step(replace(creep, t=t + 3.1, speed_mps=0.0))
    m.step(replace(creep, t=t + 3.1 + m.ctx.cfg["settle.still_s"], speed_mps=0.0))
    assert m.name == "SETTLED" and m.ctx.marks["disarm_asked"].startswith("still")
    m.step(replace(creep, t=t + 3.2 + m.ctx.cfg["settle.still_s"], speed_mps=0.0, armed=False))
    assert m.name == "LANDED" and "HEARTBEAT" in m.history[-1]["reason"]


def test_without_a_velocity_the_vehicle_is_not_disarmed_nor_the_landing_started():
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    blind = replace(OK, range_m=0.2, script_state=13, speed_mps=None, position_m=None)
    m.step(replace(blind, t=t + 2.0))
    assert m.name == "SETTLED"
    m.step(replace(blind, t=t + m.ctx.cfg["settle.timeout_s"] + 0.1))
    # held on the roof and said so: neither disarmed blind nor handed to the autopilot
    assert m.name == "SETTLED"
    assert any(c[0] == "statustext" and "position unknown" in c[1] for c in act.calls), act.calls[-3:]
    assert not {"disarm", "release", "set_mode"} & set(act.names())
    m2, _, _ = make()
    run_to(m2, "ABORTED", base=replace(OK, speed_mps=None))
    assert any("no velocity" in h["reason"] for h in m2.history)


def test_the_legs_rebound_when_the_thrust_stops_is_not_a_slide():
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    # as flown on a 37 deg roof: up to ~0.2 m/s for ~0.2 s, 3 cm in all, then at rest
    for i, (v, dx) in enumerate([(0.05, 0.0), (0.15, 0.01), (0.18, 0.02), (0.13, 0.025), (0.06, 0.03)]):
        m.step(
            replace(
                OK, t=t + 0.02 * (i + 1), range_m=0.2, script_state=13, speed_mps=v, position_m=(dx, 0, 0)
            )
        )
        assert m.name == "SETTLED", (v, dx)
    rest = replace(OK, range_m=0.2, script_state=13, speed_mps=0.0, position_m=(0.03, 0, 0))
    m.step(replace(rest, t=t + 0.2))
    m.step(replace(rest, t=t + 0.2 + m.ctx.cfg["settle.still_s"]))
    assert m.name == "SETTLED" and "disarm" in act.names()  # asked; LANDED once it is seen made
    m.step(replace(rest, t=t + 0.3 + m.ctx.cfg["settle.still_s"], armed=False))
    assert m.name == "LANDED"


def test_armed_ends_when_the_autopilot_disarms_before_the_cut():
    """Feet on the roof before the range reached the cut height: the autopilot's land detector
    disarms, the script cannot cut any more; ARMED must not wait for a cut for ever (found by the
    soak benchmark)."""
    m, _, _ = make()
    t = run_to(m, "ARMED")
    m.step(replace(OK, t=t + 0.1, range_m=0.35, armed=False))
    assert m.name == "LANDED" and "before the cut" in m.history[-1]["reason"]
    m, _, _ = make()
    t = run_to(m, "ARMED")
    m.step(replace(OK, t=t + 0.1, range_m=2.5, armed=False))
    assert m.name == "ABORTED" and "in the air" in m.history[-1]["reason"]


def test_a_vehicle_re_armed_after_it_disarmed_in_the_descent_gets_only_the_unforced_disarm():
    """Found by Hypothesis (test_machine_properties): DESCEND, the autopilot disarms on the
    ground, then the vehicle is armed again. LANDED asks for the disarm ArduCopter grants only
    with its land detector saying landed; no forced disarm, no reverse thrust, no impact seen."""
    m, act, _ = make("DESCEND")
    m.step(replace(OK, t=0.1, range_m=0.3, armed=False))
    assert m.name == "LANDED", m.history
    act.calls.clear()
    m.step(replace(OK, t=0.2, range_m=0.0, armed=False))
    m.step(replace(OK, t=0.3, range_m=0.0, armed=True))
    assert [c[0] for c in act.calls] == ["disarm_on_ground"], act.calls


def up(m: float) -> tuple[float, float, float]:
    """LOCAL_POSITION_NED ``m`` metres above where the take-off began (NED: up is -z)."""
    return (0.0, 0.0, -m)


def _to_takeoff():
    m, _, _ = make()
    t = run_to(m, "LANDED")
    m.step(replace(OK, t=t + 0.02, range_m=0.1, armed=False, takeoff_request=True))
    assert m.name == "TAKEOFF"
    return m, t + 0.02


@pytest.mark.parametrize("spike_s", [0.02, 0.3, 0.9])
def test_a_rangefinder_spike_on_the_ground_does_not_loosen_the_legs(spike_s):
    """Found by the soak benchmark: one reading of 2.4 m on the ground took the vehicle for clear."""
    m, t = _to_takeoff()
    for _ in range(int(spike_s / 0.02)):  # the spike
        t += 0.02
        m.step(replace(OK, t=t, range_m=2.42))
    for _ in range(50):  # back on the ground: 0.1 m, for a second
        t += 0.02
        m.step(replace(OK, t=t, range_m=0.1))
    assert m.name == "TAKEOFF", m.history[-1]


@pytest.mark.parametrize("spike_s", [0.3, 1.5])
def test_a_spike_that_is_the_first_valid_reading_does_not_loosen_the_legs(spike_s):
    """Found by the soak on ArduCopter: on the roof the body sat 0.07 m up, under the sensor's
    minimum (no valid reading), and a 0.25 s spike of 2.42 m was the first valid one: it seeded
    the chain and loosened the legs. LOCAL_POSITION_NED shows no climb: the legs stay clamped,
    until the vehicle has climbed the clear height (less the height estimate's tolerance)."""
    m, act, _ = make()
    t = run_to(m, "LANDED") + 0.02
    ground = replace(OK, range_m=0.07, range_ok=False, position_m=up(0.0))
    m.step(replace(ground, t=t, armed=False, takeoff_request=True))
    assert m.name == "TAKEOFF"
    for _ in range(10):
        t += 0.02
        m.step(replace(ground, t=t))
    for _ in range(int(spike_s / 0.02)):
        t += 0.02
        m.step(replace(ground, t=t, range_m=2.42, range_ok=True))
    for _ in range(25):
        t += 0.02
        m.step(replace(ground, t=t))
    assert m.name == "TAKEOFF", m.history[-1]
    assert "loosen_legs" not in act.names()
    assert any(c[:1] == ("statustext",) and "not climbed" in c[1] for c in act.calls)
    rise = 0.0  # now the vehicle climbs at 1 m/s, the range with it
    while m.name == "TAKEOFF" and rise < 2.0:
        t += 0.02
        rise += 0.02
        m.step(replace(ground, t=t, range_m=0.07 + rise, range_ok=0.07 + rise >= 0.2, position_m=up(rise)))
    assert m.name in ("RESET", "READY") and rise >= 0.8 - 0.15, (rise, m.history[-2:])


def test_the_legs_loosen_after_a_steady_climb_past_the_clear_height_and_after_a_dropout():
    m, t = _to_takeoff()
    rng = 0.1
    for _ in range(500):
        if m.name != "TAKEOFF":
            break
        t += 0.02
        rng += 0.02  # 1 m/s
        m.step(replace(OK, t=t, range_m=rng, position_m=up(rng - 0.1)))
    assert [h["to"] for h in m.history][-2:] in (["TAKEOFF", "RESET"], ["RESET", "READY"]), m.history[-2:]
    assert rng >= 0.8 + HOLD_S * 1.0 - 0.03  # held clear for HOLD_S
    m, t = _to_takeoff()
    t += 2.0  # no valid reading while climbing 2 m, then the sensor is back far above
    seen_at = None
    for i in range(200):
        t += 0.02
        m.step(replace(OK, t=t, range_m=2.1 + 0.02 * i, position_m=up(2.0 + 0.02 * i)))
        if m.name != "TAKEOFF":
            seen_at = i * 0.02
            break
    assert seen_at is not None and seen_at >= HOLD_S  # believed as a new chain after a hold


@pytest.mark.parametrize("tilt", [20.0, None])
def test_a_range_read_with_the_body_tilted_does_not_loosen_the_legs(tilt):
    """Found by the soak: leaving a 40 deg roof the body swung 20-25 deg and the tilted beam read
    0.84-1.14 m over the slope with the body 0.71-0.82 m above it; the legs were loosened there.
    Readings above the clear height count only with the body level (a missing attitude is not)."""
    m, t = _to_takeoff()
    rng = 0.1
    for _ in range(100):  # climbing at 1 m/s through and past the clear height, tilted
        t += 0.02
        rng += 0.02
        m.step(replace(OK, t=t, range_m=rng, tilt_deg=tilt, position_m=up(rng - 0.1)))
    assert m.name == "TAKEOFF", m.history[-1]
    level_at = t
    for _ in range(100):  # the body levels at 2.1 m: clear after the hold
        t += 0.02
        if m.step(replace(OK, t=t, range_m=rng, tilt_deg=4.0, position_m=up(rng - 0.1))) != "TAKEOFF":
            break
    assert (
        m.history[-1]["to"] in ("RESET", "READY")
        and "clear of the ground" in m.history[-2 if m.name == "READY" else -1]["reason"]
    )
    assert t - level_at >= HOLD_S


def test_takeoff_without_a_trustworthy_range_ends_with_the_legs_clamped():
    """Found by the soak: the vehicle climbed out of the rangefinder's reach during a dropout and
    TAKEOFF waited for ever. The legs stay clamped (safe in the air), the vehicle is handed to
    LOITER (not left hovering in GUIDED) and the pilot is told."""
    m, t = _to_takeoff()
    for k in range(1000):
        t += 0.02
        climbed = (0.0, 0.0, -min(3.0, 0.02 * k))  # NED: it rose 3 m
        if m.step(replace(OK, t=t, range_m=3.0, range_ok=False, position_m=climbed)) != "TAKEOFF":
            break
    assert m.name == "READY" and "legs left clamped" in m.history[-1]["reason"], m.history[-1]
    assert ("set_mode", "LOITER") in m.ctx.act.calls
    assert 15.0 <= t - m.history[-2]["t"] < 15.1


def test_a_take_off_that_never_climbs_is_disarmed_on_the_roof():
    """Armed, released and asked to climb, the vehicle never left the roof (its height did not
    rise): it was left READY, armed on the roof, idling for ever (DISARM_DELAY 0). Now the disarm
    is asked there, again each second, and the landing ends LANDED once it is disarmed."""
    from slopelander.controller.states.takeoff import GIVE_UP_S

    m, t = _to_takeoff()
    act = m.ctx.act
    on_roof = replace(OK, range_m=0.2, range_ok=True, position_m=(0.0, 0.0, 0.05))
    t0 = t
    while t < t0 + GIVE_UP_S + 2.5:
        t += 0.02
        m.step(replace(on_roof, t=t))
    assert m.name == "TAKEOFF" and 2 <= act.names().count("disarm_on_ground") <= 4, act.names()
    m.step(replace(on_roof, t=t + 0.02, armed=False))
    assert m.name == "LANDED" and "no climb within" in m.history[-1]["reason"]


class RefusesToDisarm(Recorder):
    """An autopilot whose land detector says the vehicle flies: every unforced disarm refused."""

    def refused(self, key: str) -> bool:
        return key == "disarm_on_ground"


def _drift_off_the_roof(m, t, estimate, heading=None):
    """Found on ArduCopter: leaving a 35 deg roof (falling north, the way the vehicle faces) the
    tilted body was pushed 3.4 m downhill and ended 0.85 m lower than it began, 1.5 m over the
    roof; the range read that, level. Steps until the machine leaves TAKEOFF (or 30 s)."""
    slope = math.tan(math.radians(35.0))
    for k in range(1500):
        t += 0.02
        north = min(3.4, 0.02 * k)  # 1 m/s downhill
        height = min(1.5, 0.1 + 0.02 * k * 0.5)
        down = north * slope - height + 0.1  # NED z: the roof falls faster than the body rises
        inp = replace(
            OK,
            t=t,
            range_m=height,
            tilt_deg=2.0,
            position_m=(north, 0.0, down),
            slope_measured=estimate,
            heading_deg=heading,
        )
        if m.step(inp) != "TAKEOFF":
            break
    return t


def test_a_take_off_that_drifts_downhill_off_a_slope_loosens_the_legs_by_its_rise_over_the_roof():
    """The climb that must bear out a clear range is the rise over the roof plane the survey
    measured, not over the take-off spot's height: the demo on ArduCopter otherwise hovered 1.6 m
    over the roof with the legs clamped, asking the autopilot to disarm it, until its 60 s ran out."""
    from slopelander.controller.slope_estimate import SlopeEstimate

    roof = SlopeEstimate(
        slope_deg=35.1, sigma_deg=0.6, refusal=None, spot_x_m=0.0, heading_deg=0.0, cross_deg=-1.4
    )
    for estimate, heading, slope in ((roof, None, None), (None, 0.0, 35.0)):  # the survey's, or the landing's
        m, t = _to_takeoff()
        m.ctx.slope_deg = slope
        _drift_off_the_roof(m, t, estimate, heading)
        assert (
            m.history[-1]["to"] in ("RESET", "READY")
            and "clear of the ground" in (m.history[-2 if m.name == "READY" else -1]["reason"])
        ), m.history[-2:]
        assert "disarm_on_ground" not in m.ctx.act.names()


def test_without_a_measured_roof_a_downhill_drift_is_no_climb_and_a_refused_disarm_ends_in_loiter():
    """Without a slope or a heading only the height counts (a drift uphill must not be credited): the legs
    stay clamped; the autopilot refuses the disarm (it flies), and after DISARM_REFUSED_S the
    vehicle is handed to LOITER, not asked to disarm for ever."""
    from slopelander.controller.states.takeoff import DISARM_REFUSED_S, GIVE_UP_S

    m, t0 = _to_takeoff()
    m.ctx.act.__class__ = RefusesToDisarm
    m.ctx.slope_deg = 35.0  # the slope, but no heading
    t = _drift_off_the_roof(m, t0, None)
    assert m.name == "READY" and "refuses to disarm" in m.history[-1]["reason"], m.history[-1]
    assert "loosen_legs" not in m.ctx.act.names() and ("set_mode", "LOITER") in m.ctx.act.calls
    assert GIVE_UP_S + DISARM_REFUSED_S <= t - t0 < GIVE_UP_S + DISARM_REFUSED_S + 0.1


@pytest.mark.parametrize(
    ("heading", "move", "expect"),
    [
        (0.0, (1.0, 0.0, 0.0), 1.0),  # 1 m north, the way a 45 deg roof falls: 1 m over it
        (90.0, (0.0, 1.0, 0.2), 0.8),  # facing east, 1 m east and 0.2 m lower
        (0.0, (-1.0, 0.0, -0.5), -0.5),  # uphill 1 m while rising 0.5: closer to the roof
        (0.0, (0.0, 1.0, 0.0), math.tan(math.radians(10.0))),  # to the right, where it falls 10 deg
    ],
)
def test_rise_over_roof_follows_the_plane(heading, move, expect):
    from slopelander.controller.roof import rise_over_roof

    start = (5.0, 5.0, 1.0)
    now = tuple(a + b for a, b in zip(start, move, strict=True))
    assert rise_over_roof(start, now, 45.0, heading, 10.0) == pytest.approx(expect)
    assert rise_over_roof((0.0, 0.0, 0.0), (3.0, 0.0, -0.2), 45.0, None) == pytest.approx(0.2)


def test_checks_refuse_downhill_legs_that_did_not_spring_back():
    """Every preset assumes the downhill legs extended (37.5 deg); legs left bent by the last
    landing are refused before the descent, not landed on."""
    from slopelander.controller.states.checks import Checks

    m, _, _ = make()
    ok = replace(OK, downhill_angles_deg=(37.3, 37.6))
    assert Checks().step(m.ctx, ok) == ("DESCEND", "checks passed")
    bent = replace(ok, downhill_angles_deg=(37.4, 22.0))
    move = Checks().step(m.ctx, bent)
    assert move[0] == "ABORTED" and "downhill legs at 22.0 deg" in move[1]


def test_a_refused_take_off_is_sent_again_once_armed():
    """Found by the soak: on a lossy link the take-off arrived before the arm, was refused, and the
    vehicle sat armed on the roof."""
    m, t = _to_takeoff()
    act = m.ctx.act
    act.refused = lambda key: key == "takeoff"  # what MavActions reports from the command's answer
    sent = len([c for c in act.calls if c[0] == "takeoff"])
    for _ in range(150):  # 3 s on the roof, armed, the take-off refused
        t += 0.02
        m.step(replace(OK, t=t, range_m=0.1, armed=True))
    again = len([c for c in act.calls if c[0] == "takeoff"]) - sent
    assert 2 <= again <= 3, again  # once a second
    m, t = _to_takeoff()
    m.ctx.act.refused = lambda key: key == "takeoff"
    for _ in range(150):  # disarmed: sending the take-off again would only be refused again
        t += 0.02
        m.step(replace(OK, t=t, range_m=0.1, armed=False))
    assert len([c for c in m.ctx.act.calls if c[0] == "takeoff"]) == 1


def test_still_is_not_disarmed_while_the_script_ramps_the_reverse_thrust_down():
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    still_s = m.ctx.cfg["settle.still_s"]
    rest = replace(OK, range_m=0.2, accel_mps2=9.80665, speed_mps=0.0, position_m=(0.0, 0.0, 0.0))
    m.step(replace(rest, t=t + 0.01, script_state=12))
    m.step(replace(rest, t=t + still_s + 0.1, script_state=12))  # still long enough, but ramping
    assert m.name == "SETTLED" and "disarm" not in act.names()
    m.step(replace(rest, t=t + still_s + 0.2, script_state=13))  # the ramp is over: HOLD
    assert m.name == "SETTLED" and "disarm" in act.names()  # asked; LANDED once it is seen made
    m.step(replace(rest, t=t + still_s + 0.3, script_state=13, armed=False))
    assert m.name == "LANDED"


def test_the_descent_below_the_arm_height_waits_for_the_scripts_reflex():
    """A refused arm (emergency stop, a system-id mismatch) must not fly the vehicle into the roof
    with its motors running: ARMED hovers until the script reports ARMED, and aborts in the air
    after ``reflex.confirm_timeout_s`` without it."""
    m, act, _ = make()
    t = run_to(m, "DESCEND")
    m.step(replace(OK, t=t + 0.02, range_m=1.4, script_state=0))
    assert m.name == "ARMED"
    n = len(act.calls)
    m.step(replace(OK, t=t + 0.1, range_m=1.4, script_state=0))
    assert ("descend", 0.0) in act.calls[n:]  # hovering, not descending
    m.step(replace(OK, t=t + 0.3, range_m=1.4, script_state=10))
    assert ("descend", m.ctx.cfg["descent.rate_mps"]) in act.calls[n:]  # confirmed: down it goes
    m2, act2, _ = make()
    t = run_to(m2, "DESCEND")
    m2.step(replace(OK, t=t + 0.02, range_m=1.4, script_state=0))
    limit = m2.ctx.cfg["reflex.confirm_timeout_s"]
    m2.step(replace(OK, t=t + 0.02 + limit + 0.05, range_m=1.4, script_state=0))
    assert m2.name == "ABORTED" and "reflex not armed" in m2.history[-1]["reason"]
    armed_at = next(i for i, c in enumerate(act2.calls) if c[0] == "reflex_arm")
    descents = [c[1] for c in act2.calls[armed_at:] if c[0] == "descend"]
    assert descents and all(v <= 0.0 for v in descents), descents  # never descended unconfirmed


def test_an_abort_after_contact_keeps_the_motors_held_on_the_roof():
    """The landing's wall-clock timeout (or any abort) after contact, with the script holding the
    motors of an armed vehicle, is not a hand-over to LOITER: it stays SETTLED."""
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    n = len(act.calls)
    held = replace(OK, t=t + 0.1, range_m=0.2, script_state=13)
    m.transition("ABORTED", "landing not finished within 120 s", held)
    assert m.name == "SETTLED"
    assert not {"release", "reflex_abort", "set_mode"} & {c[0] for c in act.calls[n:]}
    # the script let go (it gave the motors back: the vehicle left the roof): then it is aborted
    m.transition("ABORTED", "left the roof", replace(held, script_state=0))
    assert m.name == "ABORTED"


def test_a_link_lost_before_contact_and_back_after_it_judges_the_vehicle_on_the_roof():
    m, act, _ = make()
    t = run_to(m, "ARMED")
    m.step(replace(OK, t=t + 0.02, range_m=1.0, script_state=10, link_ok=False))
    assert m.name == "LINK_LOST"
    n = len(act.calls)
    m.step(replace(OK, t=t + 3.0, range_m=0.2, script_state=13, link_ok=True))
    assert m.name == "SETTLED", m.history[-1]
    assert not {"release", "set_mode"} & {c[0] for c in act.calls[n:]}


def test_the_timeout_while_the_link_is_out_after_the_script_landed_keeps_the_motors_held():
    """Found by the property test: the link lost in ARMED, the script's last word RVT (it met the
    roof meanwhile), then the landing's timeout: no state had marked an impact, and the abort
    went through (reflex abort, release, LOITER). The script's RVT or HOLD is contact too."""
    m, act, _ = make()
    t = run_to(m, "ARMED")
    m.step(replace(OK, t=t + 0.02, range_m=1.0, script_state=10, link_ok=False))
    assert m.name == "LINK_LOST"
    n = len(act.calls)
    out = replace(OK, t=t + 1.0, range_m=1.0, script_state=12, link_ok=False)
    m.transition("ABORTED", "landing not finished within 120 s", out)
    assert m.name != "ABORTED", m.history[-1]
    assert not {"release", "reflex_abort", "set_mode"} & {c[0] for c in act.calls[n:]}


@pytest.mark.parametrize("then", ["link back", "timeout"])
def test_a_script_gone_silent_after_it_met_the_roof_is_judged_on_the_roof_not_handed_to_loiter(then):
    """Found by the property test: the link lost in ARMED, the script reported RVT (the vehicle
    met the roof meanwhile), then fell silent; the link came back (or the landing timed out) and
    the silent script read as "not holding": ABORTED, LOITER asked of a vehicle armed on the roof.
    A silent script after contact is judged in SETTLED (the forced disarm once still)."""
    m, act, _ = make()
    t = run_to(m, "ARMED")
    m.step(replace(OK, t=t + 0.02, range_m=1.0, script_state=10, link_ok=False))
    m.step(replace(OK, t=t + 0.5, range_m=0.2, script_state=12, link_ok=False))  # RVT, link out
    assert m.name == "LINK_LOST"
    n = len(act.calls)
    silent = replace(OK, t=t + 2.0, range_m=0.2, script_state=12, script_present=False, speed_mps=0.0)
    if then == "link back":
        m.step(silent)
    else:
        m.transition("ABORTED", "landing not finished within 120 s", replace(silent, link_ok=False))
    assert m.name == "SETTLED", m.history[-1]
    assert not {"release", "reflex_abort", "set_mode"} & {c[0] for c in act.calls[n:]}


def test_a_script_that_disarmed_as_asked_is_not_taken_for_one_that_let_go():
    """The script says IDLE as it disarms; the HEARTBEAT saying disarmed comes up to a second
    later (found flying: SETTLED aborted "the script gave the motors back" 1 s before LANDED)."""
    m, _act, _ = make()
    t = run_to(m, "SETTLED")
    rest = replace(OK, range_m=0.2, script_state=13, speed_mps=0.0)
    i = 1
    while "disarm_asked" not in m.ctx.marks and i < 200:
        m.step(replace(rest, t=t + 0.02 * i))
        i += 1
    t1 = t + 0.02 * i
    m.step(replace(rest, t=t1, script_state=0))  # IDLE: disarmed, the HEARTBEAT not yet
    m.step(replace(rest, t=t1 + 0.8, script_state=0))
    assert m.name == "SETTLED"
    m.step(replace(rest, t=t1 + 0.9, script_state=0, armed=False))
    assert m.name == "LANDED"
    # unasked, a script that lets go while armed hands the landing to the autopilot
    m2, _, _ = make()
    t = run_to(m2, "SETTLED")
    m2.step(replace(rest, t=t + 0.05, script_state=0, speed_mps=0.3))
    m2.step(replace(rest, t=t + 0.5, script_state=0, speed_mps=0.3))
    assert m2.name == "ABORTED" and "gave the motors back" in m2.history[-1]["reason"]


@pytest.mark.parametrize(
    ("range_m", "armed", "back_to"),
    [(0.2, True, "TAKEOFF"), (0.2, False, "LANDED"), (None, True, "TAKEOFF"), (2.0, True, "ABORTED")],
    ids=["armed-on-the-roof", "disarmed-on-the-roof", "range-unknown", "clear-of-the-roof"],
)
def test_a_link_lost_in_the_takeoff_and_back_never_leaves_it_armed_on_the_roof_in_loiter(
    range_m, armed, back_to
):
    """TAKEOFF row: a vehicle still below the clear height when the link comes back is not aborted
    to LOITER armed on the roof (seen on the stand-in: it slid 20 m down the roof that way)."""
    m, act, _ = make()
    run_to(m, "LANDED")
    t = 300.0
    m.step(replace(OK, t=t, range_m=0.1, armed=False, takeoff_request=True))
    assert m.name == "TAKEOFF"
    m.step(replace(OK, t=t + 0.1, range_m=0.2, link_ok=False, takeoff_request=True))
    assert m.name == "LINK_LOST"
    n = len(act.calls)
    back = replace(OK, t=t + 3.0, range_m=range_m, range_ok=range_m is not None, armed=armed)
    m.step(back)
    assert m.history[-1]["from"] == "LINK_LOST" and m.history[-1]["to"] == back_to, m.history[-1]
    if back_to != "ABORTED":
        assert ("set_mode", "LOITER") not in act.calls[n:]


def test_the_legs_reaching_their_preset_say_the_angles_the_board_reported_within_a_statustext():
    """The pilot's log keeps the companion's STATUSTEXT (ArduPilot logs it as MSG), so the angles
    the board reported when the legs reached the preset are in the autopilot's own log for
    ``slopelander compare FLIGHT.bin``: within the 50 characters a STATUSTEXT carries."""
    m, act, _ = make()
    legs = replace(OK, uphill_angles_deg=(25.6, 25.8), downhill_angles_deg=(37.5, 37.5))
    run_to(m, "DESCEND", base=legs)
    reason = next(h["reason"] for h in m.history if h["to"] == "CHECKS")
    assert reason == "legs within tolerance at 25.7/37.5 deg", reason
    said = f"SL CHECKS: {reason}"
    assert len(said) <= 50 and said in [c[1] for c in act.calls if c[0] == "statustext"], act.calls
    m2, _, _ = make()
    run_to(m2, "DESCEND")  # a board that reports no angles: nothing made up
    assert next(h["reason"] for h in m2.history if h["to"] == "CHECKS") == "legs within tolerance"


class RefusesToArm(Recorder):
    """An autopilot that answers every arm with a refusal (ArduCopter with the pilot's throttle
    stick up: "Arm: Throttle (RC3) is not neutral")."""

    def refused(self, key: str) -> bool:
        return key == "arm"


def test_a_take_off_the_autopilot_will_not_arm_for_is_asked_again_then_ends_landed():
    """Found on ArduCopter's rule in the stand-in: TAKEOFF waited out its 15 s for a clear range
    with the vehicle disarmed on the roof and ended READY ("legs left clamped"), as if it flew."""
    from slopelander.controller.states.takeoff import ARM_RETRY_S, ARM_WAIT_S

    act = RefusesToArm()
    m = Machine(Context(cfg=load_config(), act=act, preset=(0.8, 1.5), next_preset=(0.6, 1.2)), io.StringIO())
    t = run_to(m, "LANDED")
    m.step(replace(OK, t=t + 0.02, range_m=0.1, armed=False, takeoff_request=True))
    assert m.name == "TAKEOFF"
    asked = act.names().count("takeoff")
    t0 = t + 0.02
    while m.name == "TAKEOFF" and t < t0 + ARM_WAIT_S + 1.0:
        t += 0.1
        m.step(replace(OK, t=t, range_m=0.1, armed=False))
    assert m.name == "LANDED", m.history[-1]
    assert "take-off refused" in m.history[-1]["reason"] and "throttle" in m.history[-1]["reason"]
    again = act.names().count("takeoff") - asked
    assert ARM_WAIT_S / ARM_RETRY_S - 2 <= again <= ARM_WAIT_S / ARM_RETRY_S + 1, again
    assert "loosen" not in " ".join(act.names())  # legs clamped on the roof


def test_a_failed_take_off_waits_for_the_request_to_be_let_go_and_given_again():
    """Found by the soak on the simulated vehicle: with the pilot's request held (a switch left
    up) and the autopilot refusing to arm, LANDED -> TAKEOFF -> LANDED went round every 10 s until
    the run gave up. A failed take-off now needs the request released and given anew."""
    from slopelander.controller.states.takeoff import ARM_WAIT_S

    act = RefusesToArm()
    m = Machine(Context(cfg=load_config(), act=act, preset=(0.8, 1.5), next_preset=(0.6, 1.2)), io.StringIO())
    t = run_to(m, "LANDED")
    held = replace(OK, range_m=0.1, armed=False, takeoff_request=True)
    for _ in range(int(3 * ARM_WAIT_S / 0.1)):
        t += 0.1
        m.step(replace(held, t=t))
    assert [h["to"] for h in m.history].count("TAKEOFF") == 1, [h["to"] for h in m.history]
    assert m.name == "LANDED" and "release and ask again" in " ".join(map(str, act.calls))
    m.step(replace(held, t=t + 0.1, takeoff_request=False))
    assert m.name == "LANDED"
    m.step(replace(held, t=t + 0.2))
    assert m.name == "TAKEOFF", m.history[-1]


def test_an_abort_asks_for_loiter_again_while_the_autopilot_stays_in_guided():
    """A lost mode command (and its retries) must not leave the vehicle in GUIDED: LOITER is
    asked for every REASK_S while the autopilot reports GUIDED, armed; the pilot is told once
    after TELL_AFTER asks; once it reports another mode, nothing more is asked."""
    from slopelander.controller.states.aborted import REASK_S, TELL_AFTER

    m, act, _ = make()
    limit = m.ctx.cfg["legs.ready_timeout_s"]
    t = 0.0
    while m.name != "ABORTED":  # the legs never ready: aborted before the descent, in the air
        t += 0.02
        m.step(replace(OK, t=t, legs_ready=False))
        assert t < limit + 1.0
    asks = lambda: act.calls.count(("set_mode", "LOITER"))  # noqa: E731
    assert asks() == 1
    m.step(replace(OK, t=t + REASK_S / 2, legs_ready=False))
    assert asks() == 1  # not before REASK_S
    for k in range(1, TELL_AFTER + 2):
        m.step(replace(OK, t=t + k * REASK_S, legs_ready=False))
    assert asks() == TELL_AFTER + 2
    told = [c for c in act.calls if c[0] == "statustext" and "LOITER not taken" in c[1]]
    assert len(told) == 1
    m.step(replace(OK, t=t + 20 * REASK_S, mode="LOITER", legs_ready=False))
    m.step(replace(OK, t=t + 30 * REASK_S, mode="STABILIZE", legs_ready=False))  # the pilot's
    m.step(replace(OK, t=t + 40 * REASK_S, armed=False, legs_ready=False))
    assert asks() == TELL_AFTER + 2


@pytest.mark.parametrize(
    ("armed", "above_home", "want"),
    [(False, 3.0, 1.6), (True, 3.0, 4.6), (True, None, 1.6), (True, -0.4, 1.2)],
)
def test_the_take_off_altitude_counts_from_home(armed, above_home, want):
    """NAV_TAKEOFF's altitude is above home (the parameter files' WPNAV_RFND_USE 0), home being
    where ArduCopter last armed: a disarmed vehicle the take-off arms climbs 1.6 m from here; an
    armed one adds its height above home (GLOBAL_POSITION_INT), or on a roof 3 m above the pad it
    armed on the command was "downwards" and refused."""
    m, act, _ = make(start="LANDED")
    m.step(replace(OK, t=0.02, armed=armed, above_home_m=above_home, script_state=13 if armed else 0))
    m.step(
        replace(
            OK,
            t=0.04,
            armed=armed,
            above_home_m=above_home,
            takeoff_request=True,
            script_state=13 if armed else 0,
        )
    )
    assert m.name == "TAKEOFF", m.history
    sent = [c for c in act.calls if c[0] == "takeoff"]
    assert sent and sent[0][1] == pytest.approx(want), sent


@pytest.mark.parametrize("state", ["PRESET", "LEGS_WAIT", "CHECKS"])
def test_a_vehicle_near_the_roof_before_the_descent_aborts_and_climbs(state):
    """Before the descent the vehicle hovers at its approach height. Found by the soak on
    ArduCopter: with its altitude estimate 0.8 m high, a vehicle hovered 0.5 m over the roof while
    the legs were set, sank, and met it under power in LEGS_WAIT. A range within the cut height
    (0.30 m) plus 0.3 m of the roof there aborts, and the abort climbs 1 m before LOITER as one
    from the descent does; at 0.61 m the legs are still awaited."""
    if state != "CHECKS":  # (CHECKS itself refuses legs that are not ready)
        m, _, _ = make(start=state)
        m.step(replace(OK, t=0.02, range_m=0.61, legs_ready=False))
        assert m.name == "LEGS_WAIT", m.history[-1]
    m, act, _ = make(start=state)
    low = replace(OK, t=0.02, range_m=0.45, legs_ready=False)
    m.step(low)
    assert m.name == "ABORTED", m.history[-1]
    assert m.history[-1]["reason"].endswith(
        "too near the roof before the descent: range 0.45 m (0.45 m vertically, under 0.60 m)"
    )
    assert ("hold", 0.3) in act.calls and "set_mode" not in act.names()
    rise_to_loiter(m, act, low)
    assert ("descend", -0.5) in act.calls  # the climb


def _reset_with(heights: list[float], legs_ready: bool = True, dt: float = 0.05):
    """RESET fed these ranges (a level body over a flat roof), one per ``dt``."""
    m, act, _ = make()
    run_to(m, "LANDED")
    t = run_to(m, "RESET", base=replace(OK, legs_ready=False), t0=100.0)
    for h in heights:
        t += dt
        m.step(replace(OK, t=t, range_m=h, legs_ready=legs_ready))
        if m.name != "RESET":
            break
    return m, act, t


def test_reset_climbs_back_when_the_vehicle_sinks_toward_the_roof():
    """Soak landing 135: an upset height estimate sank the vehicle onto the roof while its legs
    loosened. Under the clear height less 0.2 m the companion climbs, until it reads clear."""
    sink = [1.2 - 0.05 * i for i in range(16)]  # 1.20 .. 0.45 m at 1 m/s
    m, act, t = _reset_with(sink, legs_ready=False)
    climbs = [c for c in act.calls if c == ("hold", 0.5)]
    assert m.name == "RESET" and climbs, act.calls
    assert any(c[0] == "statustext" and "climbing" in c[1] for c in act.calls)
    m.step(replace(OK, t=t + 0.05, range_m=0.85, legs_ready=False))
    assert act.calls[-1] == ("hold", 0.0)


def test_reset_is_ready_only_once_the_height_is_held():
    m, _, t = _reset_with([0.5] * 4 + [0.9] * 10, legs_ready=True)  # low, then 0.5 s clear
    assert m.name == "RESET"
    for _ in range(12):  # a further 0.6 s clear: held for HELD_S
        t += 0.05
        m.step(replace(OK, t=t, range_m=0.9, legs_ready=True))
    assert m.name == "READY" and m.history[-1]["reason"].startswith("legs loosened")


def test_reset_hands_a_height_never_held_to_loiter():
    m, act, t = _reset_with([0.5], legs_ready=True)
    timeout = m.ctx.cfg["legs.ready_timeout_s"]
    m.step(replace(OK, t=t + timeout + 0.1, range_m=0.5, legs_ready=True))
    assert m.name == "READY" and "not held" in m.history[-1]["reason"]
    assert ("set_mode", "LOITER") in act.calls


def test_reset_with_the_range_clear_sends_no_climb():
    m, act, _ = _reset_with([1.6] * 30, legs_ready=True)
    assert m.name == "READY" and ("hold", 0.5) not in act.calls
