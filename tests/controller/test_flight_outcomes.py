"""Landings flown end to end by the companion's controller against the simulated vehicle and leg
board (real processes, TCP MAVLink, pseudo-terminal, lock-step), compared with the model.

On each roof (20, 35, 45 deg) the vehicle takes off once and lands several times: the legs set
to the lookup table's preset for the slope and the expected impact speed, the cut height chosen
for a free fall of 0.1 m or 0.3 m after the cut (impact ≈ 1.5 or 2.5 m/s). The vehicle reports
the state at first contact (src/slopelander_sitl/vehicle/events.py); the model, run alone for that contact
state,
the preset, the leg angles and the reverse thrust the vehicle gave, must predict the outcome class
the flight had (landed / slid / flipped). The model is given the reverse thrust as flown: held
until the companion ended it (once still, after ``reflex.reverse_thrust_ms``), then ramped down
over ``reflex.reverse_ramp_ms`` as the on-board script did (``Flight.model_conditions``).

The maps and the table keep the thrust on to the end of the model's 2 s horizon instead; checked
here instead of hidden: ended as a step (``reverse_ramp_ms`` 0), a slow 45 deg landing rests under
the thrust and slides away after it (above atan(mu_k) = 38.7 deg the feet cannot stop a slide),
which the model with the thrust as flown predicts and the model with it held does not.
With the ramp the same landing stays where it rested.
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from slopelander.controller.landing import expected_impact_speed, leg_geometry
from slopelander.controller.table import DEFAULT_TABLE, LookupTable
from slopelander.model.landing import simulate
from slopelander.model.outcome import Outcome
from slopelander_sitl.rig import Flight, Rig, config
from slopelander_sitl.vehicle.vehicle import CONTROL_HZ, PHYSICS_HZ

#: its tests share a vehicle flown by several tests (rig): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("controller/flight_outcomes")

SEQUENCE = ["PRESET", "LEGS_WAIT", "CHECKS", "DESCEND", "ARMED", "CUT", "REVERSE", "SETTLED", "LANDED"]


def contact_range(slope_deg: float) -> float:
    """Range (m) at which the uphill foot of a level vehicle touches (controller/landing.py geometry)."""
    g = leg_geometry()
    a = math.radians(g.leg_angle_deg)
    return g.leg_length_m * math.cos(a) + (g.joint_x_m + g.leg_length_m * math.sin(a)) * math.tan(
        math.radians(slope_deg)
    )


#: how well the vehicle's report pins the contact state: it reports the state after the first
#: physics step in contact (PHYSICS_HZ), so the touch itself lies up to one step earlier, and the
#: reversed outputs are stepped at CONTROL_HZ, so the reverse delay is known to one control step
CONTACT_STEP_S = 1.0 / PHYSICS_HZ
OUTPUT_STEP_S = 1.0 / CONTROL_HZ


def input_uncertainty(cond) -> list:
    """The conditions the vehicle's report cannot tell from ``cond``: the contact state taken one
    physics step earlier (vertical speed less g*dt, pitch less the rate times dt) and the reverse
    delay one output step either way."""
    earlier = replace(
        cond,
        speed=max(0.0, cond.speed - 9.80665 * CONTACT_STEP_S),
        pitch_deg=cond.pitch_deg - cond.pitch_rate_dps * CONTACT_STEP_S,
    )
    delays = [
        replace(cond, reverse_delay=max(0.0, cond.reverse_delay + d)) for d in (-OUTPUT_STEP_S, OUTPUT_STEP_S)
    ]
    return [earlier, *delays]


def model_class(outcome: Outcome) -> str:
    if outcome.success:
        return "landed"
    return {Outcome.SLID: "slid", Outcome.FLIP: "flipped"}.get(outcome, outcome.name.lower())


@pytest.fixture(scope="class")
def rig(request):
    """One vehicle per roof (class), taken off once; the landings of the class share it."""
    slope = request.cls.SLOPE
    with Rig(slope_deg=slope, seed=int(slope)) as r:
        r.take_off(3.0)
        r.last_flight = None
        yield r


def ensure_airborne(rig: Rig) -> None:
    """After a landing, the controller's own take-off and leg reset; then over the roof."""
    f = rig.last_flight
    if f is not None and f.end == "LANDED":
        assert rig.take_off_again(f) == "READY", f.history[-3:]
    elif f is not None and f.end == "ABORTED":  # a slide handed to the pilot: the pilot climbs away
        if rig.armed():  # still armed (that is the point): back to GUIDED, the goto below climbs
            rig.wait_command(rig.link.command(176, 1, 4), "GUIDED")  # MAV_CMD_DO_SET_MODE
        else:
            rig.take_off(rig.height() + 1.5, force=True)
    rig.go_over_roof(2.5)


#: how long (local s) a landing on the 45 deg roof may take (one held sliding on the roof stays
#: SETTLED, armed, motors held, the pilot told, until the rig ends the hold: slopelander_sitl.rig.HELD_S)
ROOF45_TIMEOUT_S = 45.0
#: the model's rotor time constant (model/default_parameters.yaml, rotor_time_constant) and the
#: script's spin-down allowance, two of them (slopelander.lua MS.THRUST_DECAY)
ROTOR_TAU_S = 0.05
SPIN_DOWN_S = 2 * ROTOR_TAU_S


def fly(rig: Rig, fall_m: float, timeout_s: float = 90.0, **reflex) -> tuple[Flight, str]:
    """One landing with the table's preset for this slope and fall, and where the preset came from."""
    ensure_airborne(rig)
    cut = round(contact_range(rig.slope_deg) + fall_m, 2)
    cfg = config(reflex={"cut_height_m": cut, **reflex})
    speed = expected_impact_speed(cfg["descent.rate_mps"], cut, rig.slope_deg, leg_geometry())
    p = LookupTable.load(DEFAULT_TABLE).lookup(rig.slope_deg, speed)
    flight = rig.land((p.tau_up, p.tau_down), cfg, timeout_s=timeout_s)
    rig.last_flight = flight
    return flight, f"table {p.cell} {p.outcome} for {speed:.2f} m/s"


def assert_held_sliding(rig: Rig, flight: Flight, source: str) -> None:
    """A landing that ended SETTLED (the rig ends the hold after ``slopelander_sitl.rig.HELD_S``): the vehicle
    slid after the thrust and is held on the roof, armed, motors stopped, the pilot told; neither
    disarmed nor handed back."""
    assert flight.states == SEQUENCE[:-1], (flight.story, source)
    assert "slide" in flight.lander.ctx.marks.get("said", set()), (flight.lander.ctx.marks, source)
    assert rig.armed() and rig.link.script_state == 13  # the script's HOLD
    assert not any("disarm" in h["reason"] and "not disarmed" not in h["reason"] for h in flight.history)


def check_against_the_model(rig: Rig, fall_m: float, timeout_s: float = 90.0) -> None:
    """Fly one landing; its outcome class must be the model's for the contact state the vehicle reported."""
    flight, source = fly(rig, fall_m, timeout_s)
    if flight.end == "SETTLED":  # a slide after the thrust: held on the roof, not handed back
        assert_held_sliding(rig, flight, source)
    else:
        assert flight.states == SEQUENCE, (flight.story, source)
    c = flight.contact
    assert c is not None
    assert abs(c["slope"] - rig.slope_deg) < 1e-6
    # The cut came first, then a fall. How far it fell freely varies run to run: the script cuts
    # on the second distinct 20 Hz range sample at or below the cut height (50-100 ms after the
    # crossing, 2.5-5 cm lower at 0.5 m/s), the rotors take time to spin down, and on a steep roof
    # the uphill foot meets it above the range the geometry of controller/landing.py gives; so
    # fall_m is an upper bound, and 0.1 m on the 45 deg roof can leave almost nothing. What holds
    # for every run: once the rotors have had two time constants (the script's own spin-down
    # allowance), their speed is under e^-2 of hover and their thrust, going as the speed squared,
    # less still: from then to contact the vehicle gains at least (1 - e^-2) g per second on the
    # speed it had at the cut.
    stops = rig.track.event_times("EV_STOP", flight.t_start)
    assert stops and stops[0] < c["t"]
    at_cut = [p for p in rig.track.pos if p[0] <= stops[0]]
    v_cut = -at_cut[-1][4]  # the descent speed at the cut (track z is up)
    gained = (1 - math.exp(-2)) * 9.80665 * max(0.0, c["t"] - stops[0] - SPIN_DOWN_S)
    assert c["vz"] > v_cut + gained, (c, v_cut, gained, stops[0])
    cond = flight.model_conditions()
    assert cond.reverse_percent == 100.0 and cond.reverse_delay < 0.02  # the reflex reversed at once
    # the thrust as flown: ended by the companion between its bounds, then the script's ramp
    cfg = flight.cfg
    shortest, longest = cfg["reflex.reverse_thrust_ms"] / 1000.0, cfg["reflex.reverse_max_ms"] / 1000.0
    assert shortest - 0.05 <= cond.reverse_duration <= longest + 0.05, cond
    assert cond.reverse_ramp == cfg["reflex.reverse_ramp_ms"] / 1000.0
    predicted = simulate(cond).result
    flown, figures = flight.classify(rig.slope_deg)
    # Near the flip line the model's call turns on details the report does not pin down; a
    # flipped prediction stops at the line, so its pitch margin says nothing of how near it was.
    # Either class the model gives for a condition within the report's resolution is accepted
    # (once: -80.1 deg predicted against the 80 deg line, landed flown).
    expected = {model_class(predicted.outcome)} | {
        model_class(simulate(c).result.outcome) for c in input_uncertainty(cond)
    }
    assert flown in expected, (source, cond, figures, predicted.summary(), expected)
    if flown == "landed":
        assert abs(figures["slide_m"] - predicted.slide) < 0.15, (figures, predicted.summary())


class TestRoof20:
    SLOPE = 20.0

    @pytest.mark.parametrize("fall_m", [0.1, 0.3])
    def test_a_landing_ends_as_the_model_predicts_for_the_preset_flown(self, rig, fall_m):
        check_against_the_model(rig, fall_m)

    def test_after_a_landing_the_controller_takes_off_and_the_legs_reset(self, rig):
        if rig.last_flight is None or rig.last_flight.end != "LANDED":
            fly(rig, 0.3)
        flight = rig.last_flight
        assert flight.end == "LANDED"
        assert not rig.armed()
        on_ground = rig.leg_angles()
        st = rig.legs.status
        assert all(lg.torque_nm > 1.0 for lg in st.legs)  # the preset still clamps the legs
        assert min(on_ground) < 36.0, on_ground  # the landing folded the legs in
        assert rig.take_off_again(flight) == "READY"
        assert flight.states[-3:] == ["TAKEOFF", "RESET", "READY"]
        assert rig.armed() and rig.height() > rig.surface_z(rig.track.pos[-1][1]) + 0.8
        st = rig.legs.status
        assert all(lg.state.name == "LOOSE" and abs(lg.torque_nm) < 0.05 for lg in st.legs), st
        assert all(abs(lg.angle_deg - 37.5) < 0.5 for lg in st.legs), st  # the springs reset them
        rig.last_flight = None


class TestRoof35:
    SLOPE = 35.0

    @pytest.mark.parametrize("fall_m", [0.1, 0.3])
    def test_a_landing_ends_as_the_model_predicts_for_the_preset_flown(self, rig, fall_m):
        check_against_the_model(rig, fall_m)


class TestRoof45:
    SLOPE = 45.0

    @pytest.fixture
    def rig(self):
        """A vehicle of its own for each landing: on 45 deg a landing may end with the vehicle
        sliding down the roof, held there armed (SETTLED), not ready for the next one."""
        with Rig(slope_deg=self.SLOPE, seed=45) as r:
            r.take_off(3.0)
            r.last_flight = None
            yield r

    def test_a_slow_landing_rests_under_reverse_thrust_and_stays_when_it_ramps_down(self, rig):
        flight, source = fly(rig, 0.1)
        assert flight.contact is not None and flight.states == SEQUENCE, (flight.story, source)
        predicted = simulate(flight.model_conditions()).result
        assert model_class(predicted.outcome) == "landed", predicted.summary()
        cfg = flight.cfg
        ended = next(h for h in flight.history if h["to"] == "SETTLED")
        assert "still under reverse thrust" in ended["reason"], ended
        # disarmed only after the ramp: the script left RVT before LANDED
        rvt_end = [t for t, s in rig.track.script if s != 12 and t > ended["t"]]
        ramp = cfg["reflex.reverse_ramp_ms"] / 1000.0
        assert rvt_end and rvt_end[0] - ended["t"] >= 0.9 * ramp, (rvt_end, ended)
        assert flight.time_of("LANDED") >= rvt_end[0]
        rig.wait(2.0, tick=flight.lander.poll)
        after = [p for p in rig.track.pos if p[0] >= flight.time_of("LANDED")]
        assert after and math.dist(after[0][1:3], after[-1][1:3]) < 0.02, (after[0], after[-1])
        assert flight.classify(rig.slope_deg)[0] == "landed"

    def test_ended_as_a_step_the_same_landing_rests_and_slides_once_it_stops(self, rig):
        flight, source = fly(rig, 0.1, ROOF45_TIMEOUT_S, reverse_ramp_ms=0)
        c = flight.contact
        assert c is not None and flight.end in ("LANDED", "SETTLED"), (flight.story, source)
        held = simulate(flight.model_conditions("held")).result
        assert model_class(held.outcome) == "landed", held.summary()  # the maps: held by the thrust
        cond = flight.model_conditions()
        assert cond.reverse_ramp == 0.0 and 0.5 <= cond.reverse_duration < 3.0, cond
        flown = simulate(cond).result
        assert model_class(flown.outcome) == "slid", flown.summary()  # the thrust as flown: slides
        # the thrust ended on evidence: once at rest, after its minimum, before its bound
        cfg = flight.cfg
        ended = next(h for h in flight.history if h["to"] == "SETTLED")
        assert "still under reverse thrust" in ended["reason"], ended
        stop = rig.track.event_times("EV_STOP", c["t"])  # the reflex's HOLD after the reverse thrust
        shortest, longest = cfg["reflex.reverse_thrust_ms"] / 1000.0, cfg["reflex.reverse_max_ms"] / 1000.0
        assert stop and shortest < stop[0] - c["t"] < longest, stop[0] - c["t"]
        rig.wait(2.0, tick=flight.lander.poll)
        pos = rig.track.pos
        under_thrust = [p for p in pos if stop[0] - 0.05 <= p[0] <= stop[0]]
        after = [p for p in pos if stop[0] + 1.0 <= p[0] <= stop[0] + 1.5]
        assert under_thrust and max(math.hypot(p[3], p[4]) for p in under_thrust) < 0.05  # at rest
        # and yet a foot slips once the thrust ends (docs/flight-figures.md): it slides down the roof
        assert after and min(math.hypot(p[3], p[4]) for p in after) > 0.2
        if flight.end == "SETTLED":  # seen sliding before the disarm: held on the roof, armed
            assert_held_sliding(rig, flight, source)
            holding = [out for t, out in rig.track.servo if stop[0] + 0.1 < t]
            assert holding and all(max(o) <= 1530 for o in holding), holding[-3:]  # never forward
        else:  # disarmed at rest (speed and accel still for settle.still_s), the slip came after
            t_landed = flight.time_of("LANDED")
            before = [p for p in pos if t_landed - 0.3 <= p[0] <= t_landed]
            assert before and max(math.hypot(p[3], p[4]) for p in before) <= cfg["settle.still_speed_mps"]
        assert flight.classify(rig.slope_deg)[0] == "slid"

    def test_a_slow_landing_whose_thrust_ramps_down_ends_as_the_model_predicts(self, rig):
        check_against_the_model(rig, 0.1, ROOF45_TIMEOUT_S)

    def test_a_fast_landing_ends_as_the_model_predicts_for_the_preset_flown(self, rig):
        """Issue 21: this landing cartwheels down the roof; the script's leaving-the-roof rule once
        released its motors mid-tumble (its beam read out of range high) and the companion
        aborted it to LOITER. It must end LANDED (disarmed once still) or held on the roof."""
        check_against_the_model(rig, 0.3, ROOF45_TIMEOUT_S)
