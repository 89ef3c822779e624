"""The companion on the script's contract-5 reports (FAULT 30, FAULT_HELD 31, CLIMB 14) and on a
script that falls silent, row by row of controller/script_rules.py, on an injected clock.

Before these rules a silent script read as IDLE: after the cut that was "a false cut" (LOITER
asked of a vehicle on the roof) and in SETTLED "the script let go" (the same); FAULT_HELD was not
contact, so an abort handed a held vehicle to LOITER; CLIMB in ARMED was waited on while the arm
was sent again."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from slopelander.controller.script_contract import ScriptState as S
from slopelander.controller.script_rules import RULES, reading, script_move
from slopelander.controller.states.settled import AIR_MARGIN_M, BEAM_TILT_DEG, DISARM_RETRY_S
from tests.controller.test_machine import OK, make, run_to

CUT_M = 0.3  # reflex.cut_height_m, the shipped setting


def steps(m, inp, seconds: float, dt: float = 0.02, **change):
    """Step ``seconds`` of vehicle time from ``inp.t`` with ``change``; the last input."""
    n = round(seconds / dt)
    for k in range(1, n + 1):
        cur = replace(inp, t=inp.t + dt * k, **change)
        m.step(cur)
    return cur


def sent(act, since: int) -> list:
    return [c for c in act.calls[since:] if c[0] != "statustext"]


def test_the_table_names_every_reading_it_acts_on():
    """Each row's reading is one the script can report (or SILENT/UNKNOWN), and the reading of a
    script not heard is SILENT whatever number is left in its state, never IDLE."""
    known = {s.name for s in S} | {"SILENT", "UNKNOWN"}
    assert {what for _, what in RULES} <= known
    assert reading(S.IDLE, present=False) == "SILENT"
    assert reading(99, present=True) == "UNKNOWN"
    assert script_move("CUT", S.IDLE, present=False, armed=True)[0] == "SETTLED"
    assert script_move("CUT", S.IDLE, present=True, armed=True) is None  # a real IDLE: CUT's own


@pytest.mark.parametrize("state", ["ARMED", "CUT", "REVERSE", "SETTLED"])
def test_a_faulted_hold_is_disarmed_by_asking_every_half_second_and_never_handed_to_loiter(state):
    """FAULT_HELD (the script failed from the cut on, motors held stopped): SETTLED, a DISARM asked
    every DISARM_RETRY_S while the vehicle is armed (the script disarms once still), no LOITER, no
    release, no reflex refresh; an abort (the landing's timeout) stays SETTLED; LANDED once the
    HEARTBEAT says disarmed."""
    m, act, _ = make()
    t = run_to(m, state)
    before = len(act.calls)
    # sliding a little (not still): the script is asked all the same, it judges stillness itself
    inp = replace(OK, t=t + 0.02, range_m=0.2, script_state=S.FAULT_HELD, accel_mps2=12.0, speed_mps=0.3)
    m.step(inp)
    assert m.name == "SETTLED", m.history[-2:]
    last = steps(m, inp, 2.0)
    names = [c[0] for c in sent(act, before)]
    assert "set_mode" not in names and "release" not in names and "reflex_abort" not in names
    assert "reflex_refresh" not in names and "reflex_arm" not in names
    assert 4 <= names.count("disarm") <= 5, names  # every 0.5 s over 2 s
    m.transition("ABORTED", "landing timed out", last)
    assert m.name == "SETTLED"
    m.step(replace(last, t=last.t + 0.02, armed=False))
    assert m.name == "LANDED"


def test_a_faulted_hold_that_slides_says_so_and_keeps_asking_the_disarm():
    """Found by the soak on ArduCopter: the script failed in HOLD on a 47 deg roof (FAULT_HELD),
    the vehicle slid at 1.04 m/s for minutes, the script refused the disarm while it moved, and
    the pilot was never told it slid. Now the slide is said as any held slide is, the disarm
    still asked (the script gives it once still), nothing handed to LOITER."""
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    before = len(act.calls)
    inp = replace(
        OK, t=t, range_m=0.12, script_state=S.FAULT_HELD, speed_mps=1.04, position_m=(0.0, 0.0, 0.0)
    )
    for k in range(1, 150):  # 3 s down the roof at 1.04 m/s
        inp = replace(inp, t=t + 0.02 * k, position_m=(1.04 * 0.02 * k, 0.0, 0.0))
        m.step(inp)
    texts = [c[1] for c in act.calls[before:] if c[0] == "statustext"]
    assert any(x.startswith("sliding at 1.04 m/s") for x in texts), texts
    assert "slide" in m.ctx.marks["said"] and m.name == "SETTLED"
    names = [c[0] for c in sent(act, before)]
    assert names.count("disarm") >= 5 and "set_mode" not in names and "release" not in names


@pytest.mark.parametrize("state", ["CUT", "REVERSE", "SETTLED"])
@pytest.mark.parametrize("script", ["silent", "fault"])
def test_a_dead_script_on_the_roof_is_not_read_as_idle_the_companion_disarms(state, script):
    """Silent (dead) or FAULT after the cut, the range on the roof: no LOITER, no false-cut abort;
    the companion's own unforced disarm every 0.5 s, and once the vehicle has read still for
    ``settle.still_s`` at or below the cut height the forced one (what the script would have done)."""
    m, act, _ = make()
    t = run_to(m, state)
    before = len(act.calls)
    dead = {"script_present": False} if script == "silent" else {"script_state": S.FAULT}
    inp = replace(OK, t=t + 0.02, range_m=0.2, **dead)
    m.step(inp)
    assert m.name == "SETTLED", m.history[-2:]
    last = steps(m, inp, 0.9)
    names = [c[0] for c in sent(act, before)]
    assert "set_mode" not in names and "hold" not in names and "release" not in names
    assert names.count("disarm_on_ground") == 2 and "disarm_forced" not in names  # t = 0, 0.5 s
    steps(m, last, 0.3)
    assert "disarm_forced" in act.names()
    assert ("statustext", f"SL script {script} on the roof: disarming") in act.calls
    m.step(replace(last, t=last.t + 0.4, armed=False))
    assert m.name == "LANDED"


def test_a_dead_script_on_the_roof_is_forced_only_still_and_low():
    """Moving, or reading above the cut height (the mixer may lift it), the companion only sends
    the unforced disarm (refused in the air); above the cut height plus 0.3 m it is in the air and
    the landing is aborted to the autopilot (climb setpoint, LOITER)."""
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    inp = replace(OK, t=t + 0.02, range_m=0.2, script_present=False, speed_mps=0.3)
    last = steps(m, inp, 3.0)
    assert m.name == "SETTLED" and "disarm_forced" not in act.names()
    last = steps(m, last, 3.0, range_m=CUT_M + 0.2, speed_mps=0.0)
    assert m.name == "SETTLED" and "disarm_forced" not in act.names()
    assert "disarm_on_ground" in act.names()
    m.step(replace(last, t=last.t + 0.02, range_m=CUT_M + 0.35))
    assert m.name == "ABORTED" and "in the air" in m.history[-1]["reason"]
    assert ("hold", 0.3) in act.calls and ("set_mode", "LOITER") in act.calls


@pytest.mark.parametrize(
    ("range_m", "tilt_deg", "end"),
    [
        (0.66, 47.0, "SETTLED"),  # ArduCopter: slid and pitched up on a 20 deg roof, 0.45 m vertically
        (0.66, 5.0, "ABORTED"),  # the same reading from a level body: in the air
        (0.66, None, "ABORTED"),  # the tilt unknown: the range alone, as before
        (2.0, 65.0, "SETTLED"),  # tipped past 60 deg: the beam says nothing of the ground below
        (1.26, 60.0, "SETTLED"),  # ArduCopter: lying at 60 deg on a 35 deg roof, 0.63 m vertically
        (1.26, 31.0, "SETTLED"),  # past 30 deg no vehicle hovers: lying on the roof
        (1.26, 29.0, "ABORTED"),  # within 30 deg, 1.10 m vertically: in the air
    ],
)
def test_a_dead_script_judges_the_air_by_the_beams_vertical_share(range_m, tilt_deg, end):
    """The range along a tilted body is not a height: SETTLED judges a silent script's vehicle as
    the script judges "left the roof", by ``range * cos(tilt)`` and only within 30 deg of level
    (no vehicle hovers tilted further). Before, a vehicle pitched 47 deg up on the roof read
    0.66 m, and one at 60 deg on a 35 deg roof 1.26 m, and each was handed to LOITER."""
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    inp = replace(OK, t=t + 0.02, range_m=range_m, tilt_deg=tilt_deg, script_present=False, speed_mps=0.3)
    steps(m, inp, 0.5)
    assert m.name == end, m.history[-1]
    assert (("set_mode", "LOITER") in act.calls) is (end == "ABORTED")


def test_the_companions_left_the_roof_figures_are_the_scripts():
    """SETTLED's margin and tilt bound mirror the script's LEAVE table (firmware_params/scripts)."""
    lua = (Path(__file__).parents[2] / "firmware_params" / "scripts" / "slopelander.lua").read_text()
    leave = re.search(r"^local LEAVE = \{([^}]*)\}", lua, re.M)
    assert leave, "the script's LEAVE table"
    fields = dict(re.findall(r"(\w+) = ([\d.]+)", leave.group(1)))
    assert float(fields["MARGIN_M"]) == AIR_MARGIN_M
    assert float(fields["TILT_DEG"]) == BEAM_TILT_DEG


@pytest.mark.parametrize(
    ("range_m", "tilt_deg", "forced"),
    [(0.55, 70.0, True), (0.66, 47.0, True), (0.55, 20.0, False), (0.32, 31.0, True), (0.29, 5.0, True)],
)
def test_a_dead_script_tilted_and_still_is_forced_to_disarm(range_m, tilt_deg, forced):
    """Still and tilted past 30 deg from level, the vehicle cannot be hovering (its thrust would
    push it sideways): the forced disarm, whatever the beam reads along the roof (ArduCopter: at
    rest pitched 47 deg on a 20 deg roof, 0.66 m); nearer level above the cut height, only asked."""
    m, act, _ = make()
    t = run_to(m, "SETTLED")
    inp = replace(OK, t=t + 0.02, range_m=range_m, tilt_deg=tilt_deg, script_present=False, speed_mps=0.0)
    steps(m, inp, 1.5)
    assert m.name == "SETTLED", m.history[-1]
    assert ("disarm_forced" in act.names()) is forced, tilt_deg
    assert "disarm_on_ground" in act.names()


def test_a_script_dead_in_the_fall_after_a_false_cut_hands_the_vehicle_to_the_autopilot():
    """Silent in CUT with the range high above the roof (a false cut): the autopilot flies."""
    m, act, _ = make()
    t = run_to(m, "CUT")
    m.step(replace(OK, t=t + 0.02, range_m=1.0, script_present=False))
    assert m.name == "ABORTED" and "in the air" in m.history[-1]["reason"]
    assert ("set_mode", "LOITER") in act.calls and "disarm_forced" not in act.names()


@pytest.mark.parametrize("state", ["DESCEND", "ARMED"])
@pytest.mark.parametrize("script", [S.CLIMB, S.FAULT])
def test_climb_or_fault_in_the_descent_stops_the_landing_without_re_arming(state, script):
    """CLIMB (the script's reflex lapsed: the companion's arms did not reach it) or FAULT in the
    descent: ABORTED at once, the arm never sent again, and the script's climb kept (no ABORT,
    which would end it) until the vehicle climbs or holds."""
    m, act, _ = make()
    t = run_to(m, state)
    before = len(act.calls)
    inp = replace(OK, t=t + 0.02, range_m=0.8, script_state=script, climb_mps=-0.4)
    m.step(inp)
    assert m.name == "ABORTED", m.history[-2:]
    last = steps(m, inp, 0.2)
    names = [c[0] for c in sent(act, before)]
    assert "reflex_arm" not in names and "reflex_refresh" not in names
    assert names[:2] == ["hold", "descend"] and "reflex_abort" not in names  # the rise, LOITER after
    steps(m, last, 0.5, climb_mps=0.3)  # climbing: the reflex and the script are let go
    assert "reflex_abort" in act.names()


def test_a_climb_before_the_arm_is_confirmed_is_not_waited_on():
    """Before the script confirmed the arm, CLIMB used to be waited on for confirm_timeout_s with
    the arm re-sent every refresh; it is the lapse of an arm that did reach it: stop."""
    m, act, _ = make()
    t = run_to(m, "DESCEND")
    for k in range(1, 400):
        t += 0.02
        m.step(replace(OK, t=t, range_m=max(0.9, 3.0 - 0.01 * k), script_state=0))
        if m.name == "ARMED":
            break
    assert m.name == "ARMED"
    m.step(replace(OK, t=t + 0.02, range_m=0.9, script_state=S.CLIMB))
    assert m.name == "ABORTED" and "lapsed" in m.history[-1]["reason"]
    assert "reflex_arm" not in [c[0] for c in act.calls if c[0] != "statustext"][-3:]


def test_a_fault_before_the_descent_refuses_the_landing():
    m, _, _ = make()
    m.step(replace(OK, t=0.02, script_state=S.FAULT))
    assert m.name == "ABORTED" and "fault" in m.history[-1]["reason"]


def test_link_back_to_a_faulted_hold_judges_it_on_the_roof():
    """Lost in the descent, back with the script's FAULT_HELD: the vehicle came down and the script
    failed on the roof; SETTLED (disarm), not ABORTED (LOITER)."""
    m, act, _ = make()
    t = run_to(m, "DESCEND")
    m.step(replace(OK, t=t + 0.02, link_ok=False))
    assert m.name == "LINK_LOST"
    before = len(act.calls)
    m.step(replace(OK, t=t + 3.0, range_m=0.2, script_state=S.FAULT_HELD))
    assert m.name == "SETTLED"
    assert "set_mode" not in [c[0] for c in act.calls[before:]]


def test_landed_armed_with_a_faulted_hold_asks_the_script():
    m, act, _ = make()
    t = run_to(m, "LANDED") + DISARM_RETRY_S
    before = len(act.calls)
    m.step(replace(OK, t=t + 0.02, range_m=0.2, armed=True, script_state=S.FAULT_HELD))
    assert [c[0] for c in sent(act, before)] == ["disarm"]


@pytest.mark.parametrize("script", [S.FAULT, S.FAULT_HELD])
def test_checks_refuse_a_faulted_script_and_say_reboot(script):
    """A script in FAULT or FAULT_HELD refuses everything but DISARM and ABORT until the autopilot
    restarts it: CHECKS names that (the soak on ArduCopter started a descent with a faulted script,
    aborted 1 s later on "reflex not armed")."""
    from slopelander.controller.states.checks import refusal

    assert refusal(replace(OK, script_state=script)) == "on-board script fault: reboot the autopilot"
    m, _, _ = make(start="CHECKS")
    m.step(replace(OK, t=0.02, script_state=script, armed=script == S.FAULT_HELD))
    assert m.name in ("ABORTED", "SETTLED") and "DESCEND" not in [h["to"] for h in m.history]


@pytest.mark.parametrize("script", [S.FAULT, S.FAULT_HELD])
def test_no_take_off_is_asked_of_a_faulted_script(script):
    """LANDED, disarmed, the script in a fault: a take-off request is refused, the vehicle is not
    armed or released, and the landing stays LANDED with the reason (the soak: TAKEOFF re-armed a
    faulted vehicle, then RESET loosened the legs on a range spike and it ended armed in LOITER at
    the roof). Once the script reports IDLE again (a reboot), the take-off goes ahead."""
    m, act, _ = make()
    t = run_to(m, "LANDED")
    before = len(act.calls)
    inp = replace(OK, t=t + 0.02, range_m=0.2, armed=False, script_state=script, takeoff_request=True)
    last = steps(m, inp, 3.0)
    assert m.name == "LANDED", m.history[-2:]
    names = [c[0] for c in act.calls[before:]]
    assert "takeoff" not in names and "release_for_takeoff" not in names and "release" not in names
    assert m.ctx.marks["takeoff_refused"] == "take-off refused: on-board script fault: reboot the autopilot"
    assert act.calls[before:].count(("statustext", "SL take-off refused: script fault, reboot")) == 1
    # a script the autopilot restarted reports IDLE: the pilot's take-off goes ahead
    m.step(replace(last, t=last.t + 0.02, script_state=S.IDLE))
    assert m.name == "TAKEOFF" and "takeoff" in act.names()


def test_a_take_off_entered_with_a_faulted_script_is_refused():
    """However TAKEOFF is reached, it asks no arming of a faulted script."""
    m, act, _ = make(start="LANDED")
    m.step(replace(OK, t=0.02, armed=False, script_state=S.FAULT))
    m.transition("TAKEOFF", "take-off commanded", replace(OK, t=0.04, armed=False, script_state=S.FAULT))
    assert "takeoff" not in act.names() and "release_for_takeoff" not in act.names()
    assert m.name == "LANDED" and "script fault" in m.history[-1]["reason"]
    # the pilot's request still standing: refused for the fault (the soak's FAULT_LANDED reads
    # it), not "take-off failed: release and ask again"
    m.step(replace(OK, t=0.06, armed=False, script_state=S.FAULT, takeoff_request=True))
    assert m.name == "LANDED" and "takeoff_refused" in m.ctx.marks, m.ctx.marks
    assert ("statustext", "SL take-off failed: release and ask again") not in act.calls
