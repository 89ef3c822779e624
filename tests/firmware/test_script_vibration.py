"""The impact rule of the real script (real Lua 5.3) under an F450's vibration, with the shipped
settings (issue 40, finding 6): the impact threshold and cut height of
``controller/default_config.yaml``, the accelerometer as ``tests/firmware/vibration.py`` makes it
(rotor lines and airflow at ArduPilot's own vibration limits, a frame mode ringing down after the
cut), read through ArduPilot's 20 Hz filter. Reverse thrust in the air pushes the vehicle onto the
roof: it must come only with a contact."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache
from pathlib import Path

import pytest
import vibration
from script_bench import SCRIPT, Bench
from test_script_contract import lua_locals
from test_script_reflex import REFLEX, good, setup

from slopelander.controller.config import load_config
from slopelander.controller.script_contract import Reflex, ScriptState, missed_impact_s
from slopelander_sitl.vehicle.scripting import RangeReading

CFG = load_config()
IMPACT = CFG["reflex.impact_threshold_mps2"]  # the shipped 20 m/s², not a test's own
CUT_M = CFG["reflex.cut_height_m"]
DESCENT = CFG["descent.rate_mps"]
BOUND_MS = round(missed_impact_s(CUT_M, DESCENT) * 1000)
#: past the bound a vehicle still falling freely with the range near waits this long more for the
#: impact (the script's MS.FALL_WAIT): these cuts meet no roof, so all of it is in the air
FALL_WAIT_MS = round(lua_locals(SCRIPT.read_text())["MS_FALL_WAIT"])
START_M = CUT_M + 0.25
S = ScriptState


def height(ms_after_cut: float, cut_h: float, contact_ms: float | None) -> float:
    """The range: the descent, then after the cut a fall (the thrust gone after ~30 ms), held
    where the feet meet the roof."""
    if contact_ms is not None:
        ms_after_cut = min(ms_after_cut, contact_ms)
    t = max(0.0, ms_after_cut) / 1000.0
    return cut_h - DESCENT * t - 0.5 * 9.81 * max(0.0, t - 0.03) ** 2


def reading(h: float) -> RangeReading:
    return good(h) if h >= 0.1 else RangeReading(0.05, 2, 100, 0.1, 3.0)  # too close: the ground


def fly(
    accel: Callable[[int], tuple[float, float, float]] | None,
    contact_ms: float | None = None,
    script: Path = SCRIPT,
):
    """Arm ``script`` with the shipped settings over a descent through the cut height; ``accel(ms)``
    is the filtered accelerometer, ``ms`` counted from the cut (negative before it). Returns the
    cut's tick and the ms after the cut of the reverse thrust (None: none before the bound and
    the wait for a vehicle still falling after it)."""
    b = Bench(script)
    b.run(50)
    b.io.range = good(START_M)
    setup(b)
    arm = b.command(REFLEX, Reflex.ARM, CUT_M, IMPACT, CFG["reflex.reverse_thrust_pct"], 500, 3000)
    assert arm.result == 0
    t0 = b.io.now_ms
    cut_at = cut_tick() if accel is not None else None
    seen = {"cut": None}

    def each(t: int) -> None:
        since = t - t0
        if seen["cut"] is None:
            b.io.range = reading(START_M - DESCENT * since / 1000.0)
        else:
            b.io.range = reading(height(t - seen["cut"], seen["h"], contact_ms))
        if accel is not None:
            b.io.accel_body = accel(since - cut_at)

    for _ in range(2000):
        b.run(1, each)
        if seen["cut"] is None and b.outputs()[0] == 1500:
            seen["cut"], seen["h"] = b.io.now_ms, START_M - DESCENT * (b.io.now_ms - t0) / 1000.0
        if b.io.state() == S.RVT:
            return b.io.now_ms - t0, b.io.now_ms - seen["cut"]
        if seen["cut"] is not None and b.io.now_ms - seen["cut"] > BOUND_MS + FALL_WAIT_MS + 20:
            break
    assert seen["cut"] is not None and b.io.state() == S.HOLD, b.io.sl_texts()
    return seen["cut"] - t0, None


@cache
def cut_tick() -> int:
    """When the script cuts on this descent, counted from the arm (the accelerometer plays no part)."""
    tick, rvt = fly(None)
    assert rvt is None
    return tick


def from_flight(f: vibration.Flight) -> Callable[[int], tuple[float, float, float]]:
    start = round(-f.t[0] * 1000)
    return lambda ms: f.at_ms(start + ms)


@pytest.mark.parametrize("scale", [1.0, 1.5])
def test_no_reverse_thrust_in_the_air_under_vibration_arducopter_accepts(scale: float) -> None:
    """Hover, cut and fall through the bound with no contact, at 1 and 1.5 times ArduPilot's
    acceptable vibration (VIBE 30 m/s² on z, LogAnalyzer's 2-sigma limits after the filter): the
    shipped 20 m/s² never fires. (The script of contract 4 held here too: 0 of 60 cuts up to
    1.5 times; at 1.75 and 2 times the 2 g rule itself fired 1 of 60, 2 ms after the cut:
    benchmarks/impact_vibration.py.)"""
    for seed in range(6):
        f = vibration.flight(cut_s=2.0, length_s=2.6, seed=seed, scale=scale)
        _, rvt = fly(from_flight(f))
        assert rvt is None, (seed, rvt)


@pytest.mark.parametrize("amplitude", [7.0, 8.5, 10.0])
def test_a_frame_ringing_down_after_the_cut_does_not_reverse_in_the_air(amplitude: float) -> None:
    """Issue 40: a 6-8.5 m/s² vibration after the filter (the bench case, 15-70 Hz), here a 40 Hz
    frame mode the rotors drive, ringing down once they stop, cut at 12 phases of it. Read from
    the lowest reading since the cut, a trough and the next crest, while the thrust's 1 g was still
    read, made a 1 g rise under the 2 g threshold: contract 4 reversed 8-32 ms after the cut, in
    the air, at 5 of 12 phases for 7 m/s², 11 of 12 for 8.5 and 12 of 12 for 10. The rise counts
    from 50 ms after the cut, when the rotors' thrust and drive are down to 14 %: none."""
    fired = []
    for phase_deg in range(0, 360, 30):
        f = vibration.ringing(cut_s=1.5, length_s=2.0, amplitude=amplitude, phase=math.radians(phase_deg))
        _, rvt = fly(from_flight(f))
        if rvt is not None:
            fired.append((phase_deg, rvt))
    assert not fired, fired


@pytest.mark.parametrize(
    ("contact_ms", "force", "seed"),
    [(80, 13.7, 0), (80, 13.7, 1), (120, 13.7, 2), (160, 13.7, 3), (30, 25.0, 4)],
)
def test_a_contact_under_vibration_still_reverses_within_30_ms(
    contact_ms: int, force: float, seed: int
) -> None:
    """A soft first contact after the thrust has decayed (an uphill leg near the horizontal slips:
    1.4 g more over 10 ms, as ArduCopter read it at 45 deg: 16.0 m/s² from a falling vehicle's 0.2 g) under
    the vibration ArduPilot accepts, and a hard one just after the cut: reverse thrust within
    30 ms of the contact (tests/flights, ``reversed_within_30ms``)."""
    f = vibration.flight(cut_s=2.0, length_s=2.6, seed=seed, contact=(contact_ms / 1000.0, force, 0.01))
    _, rvt = fly(from_flight(f), contact_ms=contact_ms)
    assert rvt is not None and contact_ms <= rvt <= contact_ms + 30, rvt


def test_a_contact_while_the_frame_rings_still_reverses() -> None:
    f = vibration.ringing(cut_s=1.5, length_s=2.0, amplitude=8.5, phase=0.0, contact=(0.08, 13.7, 0.01))
    _, rvt = fly(from_flight(f), contact_ms=80)
    assert rvt is not None and 80 <= rvt <= 110, rvt
