"""How a flight's reverse thrust is read from what the vehicle and the script reported
(``src/slopelander_sitl/rig.py`` ``Flight.model_conditions``), on recorded telemetry values: the events and
SL_STATE changes a flight's track holds. The flight tests read real flights the same way
(``test_flight_outcomes.py``); these cover the endings a flight shows only now and then."""

from __future__ import annotations

import math

import pytest

from slopelander_sitl.rig import Flight, Track, config

CONTACT = 10.0
RVT = 10.002  # the vehicle's EV_RVT: outputs reversed


def flight(script: list[tuple[float, int]], history: list[tuple[str, float]] = (), **reflex) -> Flight:
    track = Track()
    track.events = [("EV_CONTACT", CONTACT, CONTACT), ("EV_RVT", RVT, RVT)]
    track.script = [(9.9, 11), *script]
    cfg = config(reflex=reflex) if reflex else config()
    contact = {"t": CONTACT, "vz": 2.2, "vx": 0.0, "pitch": 0.0, "rate": 0.0, "slope": 42.0}
    hist = [{"to": to, "t": t, "reason": ""} for to, t in history]
    return Flight("LANDED", hist, (1.1, 1.7), cfg, 0.0, contact, track, None, (22.3, 37.5))


def test_the_script_leaving_rvt_for_hold_marks_the_end_of_the_ramp():
    f = flight([(10.002, 12), (11.641, 13)])
    c = f.model_conditions()
    ramp = f.cfg["reflex.reverse_ramp_ms"] / 1000.0
    assert c.reverse_ramp == ramp == 1.0
    assert c.reverse_duration == pytest.approx(11.641 - ramp - RVT)
    assert c.reverse_delay == pytest.approx(RVT - CONTACT)
    held = f.model_conditions("held")
    assert held.reverse_duration == math.inf and held.reverse_ramp == 0.0
    with pytest.raises(ValueError, match="flown"):
        f.model_conditions("ramped")


def test_a_step_end_with_no_ramp_configured():
    c = flight([(10.002, 12), (10.64, 13)], reverse_ramp_ms=0).model_conditions()
    assert c.reverse_ramp == 0.0 and c.reverse_duration == pytest.approx(10.64 - RVT)


def test_leaving_rvt_for_another_state_stops_the_outputs_at_once():
    c = flight([(10.002, 12), (10.9, 0)]).model_conditions()  # disarmed in RVT: released
    assert c.reverse_ramp == 0.0 and c.reverse_duration == pytest.approx(10.9 - RVT)


def test_handed_to_the_pilot_before_hold_is_heard_the_ramp_began_when_the_companion_ended_it():
    f = flight([(10.002, 12)], history=[("REVERSE", 10.03), ("SETTLED", 10.65), ("ABORTED", 11.6)])
    c = f.model_conditions()
    assert c.reverse_ramp == 1.0 and c.reverse_duration == pytest.approx(10.65 - RVT)


def test_held_past_the_scripts_bound_reads_as_held_to_it_then_ramped_until_rvt_ended():
    # the companion ended it at 10.6, but the script kept RVT to its 3 s bound and was released
    # (abort) 0.94 s into its ramp
    f = flight([(10.002, 12), (13.942, 0)], history=[("SETTLED", 10.6), ("ABORTED", 13.94)])
    c = f.model_conditions()
    assert c.reverse_duration == pytest.approx(3.0)
    assert c.reverse_ramp == pytest.approx(13.942 - RVT - 3.0)


def test_an_rvt_never_seen_to_end_is_held():
    c = flight([(10.002, 12)]).model_conditions()
    assert c.reverse_duration == math.inf and c.reverse_ramp == 0.0
