"""The cut reckoned on the descent (contract 7) in the real on-board script under real Lua 5.3:
a rangefinder that goes silent, or spikes, within 0.3 m of the cut height no longer lets the
descent meet the roof under power (soak on ArduCopter at 23bea36, landings 5 and 140)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from script_bench import Bench
from test_script_reflex import ARMED, BOUND_MS, CUT, CUT_M, HOLD, IDLE, RVT, arm, cut_now, good

from slopelander_sitl.vehicle.scripting import RangeReading

NO_DATA = RangeReading(0.0, 1, 0, 0.1, 3.0)  # status NoData: the sensor says nothing
BEYOND = RangeReading(3.5, 3, 100, 0.1, 3.0)  # status OutOfRangeHigh: ground past the sensor
AFTER_MS = 150  # RECKON.AFTER_MS


def fly(bench: Bench, h0: float, speed: float, ms: int, reading) -> list[tuple[int, float, int]]:
    """Descend at ``speed`` m/s (the autopilot's velocity estimate says so) from ``h0`` for ``ms``
    or until the cut; ``reading(t, h)`` is what the sensor reads. Returns (t, true height, state)
    per ms."""
    t0 = bench.io.now_ms
    bench.io.velocity = (0.0, 0.0, speed)
    out = []
    for _ in range(ms):
        h = h0 - speed * (bench.io.now_ms - t0) / 1000
        bench.io.range = reading(bench.io.now_ms - t0, h)
        bench.run(1)
        out.append((bench.io.now_ms, h, bench.io.state()))
        if out[-1][2] == CUT:
            break
    return out


def dropout_below(at_m: float):
    """Good readings down to ``at_m``, then nothing."""
    return lambda _t, h: good(h) if h > at_m else NO_DATA


def cut_of(trace) -> tuple[int, float] | None:
    return next(((t, h) for t, h, s in trace if s == CUT), None)


def test_a_dropout_just_above_the_cut_height_cuts_on_the_reckoned_descent(bench: Bench) -> None:
    bench.io.range = good(0.8)
    arm(bench)
    trace = fly(bench, 0.8, 0.5, 1600, dropout_below(0.35))
    cut = cut_of(trace)
    assert cut is not None, "the descent met the roof under power"
    last_good = max(t for t, h, _ in trace if h > 0.35)
    # three sample periods of silence from the last good sample (up to one period before the
    # last good height), then the reckoned height is already under the cut height
    assert AFTER_MS - 50 <= cut[0] - last_good <= AFTER_MS + 5
    assert 0.20 <= cut[1] <= CUT_M
    said = [x for x in bench.io.sl_texts() if "reckoned cut at" in x]
    assert said and len(said[0]) <= 50, said  # one STATUSTEXT: its text is 50 characters
    # the impact with no range at all: near by the reckoning, reverse thrust
    bench.io.accel_body = (0.0, 0.0, -45.0)
    bench.run(5)
    assert bench.io.state() == RVT


def test_the_same_dropout_cuts_nothing_on_contract_6s_rule(bench: Bench) -> None:
    """The finding reproduced: with the reckoning out of reach (the autopilot without a velocity
    estimate), a dropout 0.35 m up stays ARMED to the roof."""
    bench.io.range = good(0.8)
    arm(bench)
    t0 = bench.io.now_ms
    for _ in range(1400):
        h = 0.8 - 0.5 * (bench.io.now_ms - t0) / 1000
        bench.io.velocity = None
        bench.io.range = good(h) if h > 0.35 else NO_DATA
        bench.run(1)
    assert bench.io.state() == ARMED


def test_a_high_spike_through_the_cut_height_cuts_and_the_impact_reverses(bench: Bench) -> None:
    """Landing 140: a 0.47 s spike reading 2 m (trusted readings the chain sets aside as a glitch)
    began 0.4 m over the roof. The cut comes on the reckoning; the spike still on at the bound is
    not taken for a false cut."""
    bench.io.range = good(0.8)
    arm(bench)

    def spike(t: int, h: float) -> RangeReading:
        return good(2.0) if 0.40 >= h > 0.40 - 0.5 * 0.47 else good(max(h, 0.12))

    trace = fly(bench, 0.8, 0.5, 1600, spike)
    cut = cut_of(trace)
    assert cut is not None and 0.20 <= cut[1] <= CUT_M
    bench.io.velocity = (0.0, 0.0, 0.0)
    bench.io.range = good(2.0)
    bench.io.accel_body = (0.0, 0.0, -45.0)
    bench.run(5)
    assert bench.io.state() == RVT


def test_a_reckoned_cut_with_no_impact_holds_on_the_ground(bench: Bench) -> None:
    bench.io.range = good(0.8)
    arm(bench)
    trace = fly(bench, 0.8, 0.5, 1600, dropout_below(0.35))
    cut = cut_of(trace)
    assert cut is not None
    bench.run(cut[0] + BOUND_MS + 10 - bench.io.now_ms)
    assert bench.io.state() == HOLD
    assert bench.outputs() == [1500] * 4


def test_a_reckoned_cut_that_trusted_readings_contradict_is_released(bench: Bench) -> None:
    """The reckoning was wrong (the vehicle was higher): readings back on the chain say 0.6 m, the
    bound passes with no impact: a false cut, the motors given back."""
    bench.io.range = good(0.8)
    arm(bench)
    trace = fly(bench, 0.8, 0.5, 1600, dropout_below(0.35))
    cut = cut_of(trace)
    assert cut is not None
    bench.io.velocity = (0.0, 0.0, 0.0)
    bench.io.range = good(0.5)
    bench.io.accel_body = (0.0, 0.0, -0.3)  # nothing under it: falling freely
    bench.run(cut[0] + BOUND_MS + 10 - bench.io.now_ms)
    assert bench.io.state() == IDLE
    assert "SL: false cut, motors released" in bench.io.sl_texts()


@pytest.mark.parametrize(
    ("why", "h0", "speed", "silent"),
    [
        ("holding height", 0.45, 0.0, NO_DATA),
        ("climbing", 0.45, -0.5, NO_DATA),
        ("too slow to be a descent", 0.45, 0.1, NO_DATA),
        ("last reading far above the cut height", 1.2, 0.5, NO_DATA),
        ("ground beyond the sensor (an edge)", 0.45, 0.5, BEYOND),
    ],
)
def test_no_reckoned_cut(bench: Bench, why: str, h0: float, speed: float, silent: RangeReading) -> None:
    bench.io.range = good(h0)
    arm(bench)
    bench.io.velocity = (0.0, 0.0, speed)
    bench.run(100)
    bench.io.range = silent
    bench.run(1500 if speed <= 0.1 else int(1000 * (h0 - 0.35) / speed))
    assert bench.io.state() == ARMED, why


@settings(max_examples=40, deadline=None)
@given(
    at_m=st.floats(0.31, 0.60),
    speed=st.floats(0.25, 1.2),
)
def test_any_dropout_in_the_window_cuts_before_the_feet_and_not_above_the_cut_height(
    at_m: float, speed: float
) -> None:
    """The feet meet the roof at 0.12 m (the cut height 0.3 m less the legs' reach): every dropout
    in the window, at any descent speed the EKF reports, cuts above that and never above the cut
    height."""
    bench = Bench()
    bench.io.range = good(at_m + 0.3)
    arm(bench)
    trace = fly(bench, at_m + 0.3, speed, int(1000 * (at_m + 0.3) / speed), dropout_below(at_m))
    cut = cut_of(trace)
    assert cut is not None, (at_m, speed)
    assert cut[1] <= CUT_M + 1e-9
    # silence lasts AFTER_MS from the last good sample, taken at or above at_m
    assert cut[1] >= min(CUT_M, at_m - speed * (AFTER_MS + 5) / 1000) - 0.005
    assert cut[1] > 0.12


def test_a_range_stuck_just_above_the_cut_height_cuts_on_the_reckoned_descent(bench: Bench) -> None:
    """Soak landing 140 at ea848b5: after a spike the sensor read 0.70 m and stayed there (cut height
    0.63 m that landing). Each stuck reading agreed with the chain and renewed it: no two-sample
    cut, no reckoning, the feet met the roof under power. A reading that stops moving is silence
    for the reckoning (contract 8)."""
    bench.io.range = good(0.8)
    arm(bench)
    stuck_at = CUT_M + 0.07

    def stuck(_t: int, h: float) -> RangeReading:
        return good(h) if h > stuck_at else good(stuck_at)

    trace = fly(bench, 0.8, 0.5, 1600, stuck)
    cut = cut_of(trace)
    assert cut is not None, "the descent met the roof under power"
    assert CUT_M - 0.5 * (AFTER_MS + 60) / 1000 <= cut[1] <= CUT_M
    # the stuck readings go on after the cut: they say nothing new, the impact is still taken
    bench.io.accel_body = (0.0, 0.0, -45.0)
    bench.run(5)
    assert bench.io.state() == RVT


def test_a_steady_reading_while_holding_height_cuts_nothing(bench: Bench) -> None:
    """A vehicle that holds its height reads one value again and again: no descent, no reckoning."""
    bench.io.range = good(CUT_M + 0.05)
    arm(bench)
    bench.io.velocity = (0.0, 0.0, 0.05)
    bench.run(2000)
    assert bench.io.state() == ARMED


def test_a_slow_true_descent_reads_as_moving(bench: Bench) -> None:
    """At the slowest descent the reckoning runs at (0.2 m/s), readings in whole centimetres still
    move every sample: the cut comes from the readings, at the cut height, not from the reckoning."""
    bench.io.range = good(0.6)
    arm(bench)
    trace = fly(bench, 0.6, 0.2, 3000, lambda _t, h: good(round(h, 2)))
    cut = cut_of(trace)
    assert cut is not None
    assert not [x for x in bench.io.sl_texts() if "reckoned" in x]
    assert CUT_M - 0.2 * 0.11 <= cut[1] <= CUT_M


def test_an_accelerometer_spike_pointing_down_the_body_is_no_impact(bench: Bench) -> None:
    """Soak landing 143 at ea848b5: a 6 g, 40 ms spike 0.09 s after the cut, the body falling toward
    a 50 deg roof, fired reverse thrust 0.12 s before the feet met it. The roof can only push the
    body up through its legs (contract 8); the same spike pointing up is still taken."""
    bench.io.range = good(0.8)
    arm(bench)
    trace = fly(bench, 0.8, 0.5, 1600, lambda _t, h: good(max(h, 0.12)))
    assert cut_of(trace) is not None
    bench.io.accel_body = (0.0, 0.0, 0.0)  # falling freely
    bench.run(90)
    bench.io.accel_body = (0.0, 0.0, 60.0)  # the soak's spike: down the body
    bench.run(40)
    assert bench.io.state() == CUT
    bench.io.accel_body = (0.0, 0.0, 0.0)
    bench.run(30)
    bench.io.accel_body = (8.0, 0.0, -40.0)  # the feet on the roof
    bench.run(5)
    assert bench.io.state() == RVT


def test_a_high_spike_at_the_touchdown_hides_neither_the_impact_nor_the_roof(bench: Bench) -> None:
    """Soak landing 64 at 7425eb6: a 0.49 s spike reading 1.19 m began 0.05 s before the feet met a
    7 deg roof. The newest sample read far, so the impact was not taken, and at the bound the
    spike read as a false cut: the motors were given back on the roof. A glitch against a chain at
    the cut height is no evidence of height (contract 8)."""
    cut_now(bench)  # the range at 0.2 m, on the chain
    bench.io.accel_body = (0.0, 0.0, -0.3)
    bench.run(60)
    bench.io.range = good(1.19)  # the spike
    bench.run(50)
    bench.io.accel_body = (3.0, 0.0, -40.0)  # the feet on the roof
    bench.run(5)
    assert bench.io.state() == RVT


def test_a_carried_vehicle_is_held_whatever_a_spike_reads_at_the_bound(bench: Bench) -> None:
    """No impact seen (a soft touchdown), and the range spiking far at the bound: the vehicle is
    carried (1 g with the motors long stopped), so it stands on the roof: HOLD, not a release."""
    cut_now(bench)
    bench.io.accel_body = (0.0, 0.0, -9.81)
    bench.run(100)
    bench.io.range = good(1.19)
    cut_at = next(t for t, n, v in bench.io.named if n == "SL_STATE" and v == CUT)
    bench.run(cut_at + BOUND_MS + 10 - bench.io.now_ms)
    assert bench.io.state() == HOLD
    assert "SL: false cut, motors released" not in bench.io.sl_texts()
