"""Flight safety at the edges (issue 40), flown on both autopilots: the simulated vehicle and real
ArduCopter SITL (``SLOPELANDER_ARDUCOPTER``), each case a vehicle of its own.

- The survey pass over a roof's edge: past the gutter the rangefinder has nothing in range, the
  pass's roof guard has nothing to guard with, and the pass is aborted (back over the spot,
  LOITER) instead of flying on blind at constant height.
- The on-board script dead at the cut (its update returns nothing: ArduPilot stops running it, as
  after an error it cannot catch) and failed at the cut (an error its pcall catches: FAULT_HELD):
  the landing ends disarmed on the roof, never in LOITER armed there. The script is the shipped one
  with a line added at the top of its update, acting while ``SCR_USER1`` (a parameter ArduPilot
  keeps for scripts) names the state: 1000 + state stops it, 2000 + state raises.
- The script failed in the armed descent (FAULT, its own climb): the landing stops in the air,
  the vehicle armed in LOITER clear of the roof.
- A false cut about 1 m over the roof (a low range reading that lasts): the motors stay stopped
  through the fall and the impact is reversed.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink import mavutil

from slopelander.controller.script_contract import ScriptState
from slopelander.controller.slope_estimate import SurfaceTrack
from slopelander.controller.survey import RANGE_LOST_S, measure_slope
from slopelander_sitl.rig import TRACK_MESSAGES, Rig, config
from tests.flights.test_landings_on_both_autopilots import FALL_M, contact_range, roof_scenario

LOITER = 5
SPOT_X_M = 5.5  # slopelander_sitl.rig.OVER_ROOF_X_M, where go_over_roof hovers
GUTTER_X_M = 5.7  # the roof's top edge at x = 3 m (slopelander_sitl.rig.ROOF_X_M) plus a 2.7 m roof


def test_a_survey_pass_over_the_gutter_is_aborted_on_the_rangefinder_dropout(autopilot: str) -> None:
    """The pass's first leg flies 1 m each way along the heading (north, down the roof) from a spot
    0.2 m short of the gutter: beyond it nothing is in range. The leg is aborted within
    RANGE_LOST_S of the last in-range reading: the vehicle turns back short of the leg's end
    (before, it flew the whole metre, over 0.8 m past the gutter), comes back over the spot and is
    handed to LOITER; the estimate is refused, naming the dropout."""
    cfg = config()
    notes: list[str] = []
    with Rig(slope_deg=20.0, seed=71, autopilot=autopilot, scenario={"roof_length": GUTTER_X_M - 3.0}) as rig:
        rig.take_off(3.0)
        rig.go_over_roof(2.0)
        track = SurfaceTrack(cfg["slope.pair_window_s"])
        rig.link.add_listener(track.feed)
        t0 = rig.now
        est, took = measure_slope(rig.link, cfg, track, tick=rig.poll, note=notes.append)
        north = max(p[1] for p in rig.track.pos if p[0] >= t0)
        rig.fly_until(lambda: rig.mode() == LOITER, 5.0, "LOITER after the aborted pass")
        x, z = rig.track.pos[-1][1], rig.track.pos[-1][2]
        over = z - rig.surface_z(x)
    print(autopilot, f"north {north:.2f} m, pass {took:.1f} s;", *notes, est.refusal, sep="\n  ")
    assert took > 0 and est.slope_deg is None
    assert est.refusal.startswith("survey pass not finished: rangefinder dropout: no in-range reading"), (
        est.refusal
    )
    assert any("pass aborted, back over the spot" in n for n in notes), notes
    # turned back: the gutter, RANGE_LOST_S at the pass's speed and the braking, well short of 6.5 m
    assert north < GUTTER_X_M + cfg["slope.survey_speed_mps"] * (RANGE_LOST_S + 0.6) + 0.1, north
    assert abs(x - SPOT_X_M) < 0.4 and over > 1.5, (x, over)  # back over the spot, at the pass's height


SCRIPT = Path(__file__).resolve().parents[2] / "firmware_params" / "scripts" / "slopelander.lua"
#: where each injection goes: the top of the update ArduPilot calls (returning nothing there stops
#: the script), and the top of the step it runs under pcall (an error there is caught: a fault)
UPDATE = "local function update()\n"
STEP = "local function step()\n  local t = now()\n"
STOPS, RAISES = 1000, 2000


def injected_script(folder: Path) -> Path:
    """The shipped script that stops (its update returns nothing) or raises (in the step its
    update runs under pcall) while ``SCR_USER1`` is 1000 or 2000 plus its state."""
    source = SCRIPT.read_text()
    assert source.count(UPDATE) == 1 and source.count(STEP) == 1, "the injections' places moved"
    when = '  if param:get("SCR_USER1") == state + '
    source = source.replace(UPDATE, UPDATE + when + "1000 then return end\n")
    source = source.replace(STEP, STEP + when + '2000 then error("injected fault") end\n')
    path = folder / "slopelander.lua"
    path.write_text(source)
    return path


def set_param(rig: Rig, name: str, value: float) -> None:
    """PARAM_SET, until the autopilot's PARAM_VALUE says it holds the value (as a float32: 0.6 comes
    back as 0.60000002)."""
    mav = rig.link.conn.mav
    seen: list[float] = []

    def listen(msg) -> None:
        if msg.get_type() == "PARAM_VALUE" and msg.param_id.rstrip("\x00") == name:
            seen.append(msg.param_value)

    rig.link.add_listener(listen)

    def send() -> None:
        mav.param_set_send(
            rig.info.system, rig.info.component, name.encode(), value, mavutil.mavlink.MAV_PARAM_TYPE_REAL32
        )

    held = lambda: any(abs(v - value) < 1e-6 for v in seen)  # noqa: E731
    rig.fly_until(held, 5.0, f"set {name} to {value:g}", send=send)


SLOPE_DEG = 20.0


@pytest.mark.parametrize("how", ["dead", "fault"])
def test_a_script_dead_or_failed_at_the_cut_ends_disarmed_on_the_roof(
    autopilot: str, how: str, tmp_path
) -> None:
    """Dead at the cut: its overrides lapse 250 ms later, mid-fall or on the roof, and the mixer
    has the motors; the companion, a second later, reads it silent (not IDLE: before, that was "a
    false cut" and LOITER asked of a vehicle on the roof), judges by the range that it is on the
    roof and disarms it itself (forced once still for a second at or below the cut height).
    Failed at the cut: FAULT_HELD, the motors held; the companion asks DISARM every 0.5 s until the
    HEARTBEAT says disarmed. Either way the landing ends LANDED, disarmed, never in LOITER."""
    cut = round(max(0.3, contact_range(SLOPE_DEG) + FALL_M), 2)
    cfg = config(reflex={"cut_height_m": cut})
    mode_seen: list[int] = []
    script = injected_script(tmp_path)
    decode = TRACK_MESSAGES | {"PARAM_VALUE"}
    with Rig(slope_deg=SLOPE_DEG, seed=73, autopilot=autopilot, script=script, decode=decode) as rig:
        p, _ = rig.plan(cfg)
        rig.take_off(3.0)
        rig.go_over_roof(2.5)
        set_param(rig, "SCR_USER1", (STOPS if how == "dead" else RAISES) + ScriptState.CUT)
        rig.link.add_listener(lambda m: m.get_type() == "HEARTBEAT" and mode_seen.append(m.custom_mode))
        flight = rig.land(
            (p.tau_up, p.tau_down), cfg, timeout_s=60.0, rest_s=2.0, uphill_angle_deg=p.angle_up_deg
        )
        armed = rig.armed()
        texts = list(rig.link.statustext)
    ctx = " | ".join([f"{autopilot} {how}"] + [f"{h['to']}: {h['reason']}" for h in flight.history])
    ctx += " || " + " | ".join(str(t) for t in texts[-10:])
    print(ctx)
    assert flight.end == "LANDED" and not armed, ctx
    assert "ABORTED" not in [h["to"] for h in flight.history], ctx
    assert LOITER not in mode_seen, ctx
    reasons = " ".join(h["reason"] for h in flight.history)
    if how == "dead":
        assert "on-board script silent: the companion's own disarm" in reasons, ctx
    else:
        assert "script fault" in reasons, ctx
        assert any("fault in CUT" in str(t) for t in texts), ctx


# ------------------------------------------------------------------ a false cut low
#: vehicle time (s) the rangefinder starts reading FALSE_RANGE_M under a vehicle hovering over the
#: roof: a return off something nearer than the roof (a branch, spray), lasting long enough for the
#: script to believe it (its chain takes a lasting disagreement after 0.6 s)
SPIKE_T = 70.0
SPIKE_S = 2.0
FALSE_RANGE_M = 0.15
HOVER_OVER_ROOF_M = 1.5


def land_from_over_the_roof(rig: Rig, p, cfg, land_at_s: float, fault: str, autopilot: str):
    """Take off, hover over the roof with the legs set, land from vehicle time ``land_at_s`` (a
    scenario fault is timed by it): the flight, whether still armed, the status texts and a
    context line for the assertions."""
    rig.take_off(3.0)
    rig.go_over_roof(HOVER_OVER_ROOF_M)
    rig.set_legs(p.tau_up, p.tau_down)
    if rig.now > land_at_s:
        pytest.fail(f"{fault}'s landing at {land_at_s:g} s of vehicle time already passed ({rig.now:.1f} s)")
    rig.wait(land_at_s - rig.now)
    flight = rig.land((p.tau_up, p.tau_down), cfg, timeout_s=60.0, rest_s=2.0)
    armed = rig.armed()
    texts = [str(t) for t in rig.link.statustext]
    ctx = " | ".join([autopilot] + [f"{h['t']:.2f} {h['to']}: {h['reason']}" for h in flight.history])
    ctx += " || " + " | ".join(texts[-10:])
    print(ctx)
    return flight, armed, texts, ctx


def test_a_false_cut_low_keeps_the_motors_stopped_and_reverses_on_the_impact(autopilot: str) -> None:
    """A range reading low for a second, 1.8 m over a flat roof, cuts the motors about 1.3 m up.
    The vehicle falls freely past the script's missed-impact bound (0.35 s: the fall from the cut
    height it believes). Before, the script then judged the cut by the range: near (the false
    reading, or the true one low in the fall) it held the motors stopped, "no impact seen", and
    the vehicle met the roof in HOLD, with no reverse thrust on the impact; far, it gave the motors
    back to the mixer 0.4 m above the roof falling at 4 m/s, too late to stop. Now a vehicle still
    falling freely at the bound, too low for the motors to stop it, keeps its cut: the impact gets
    its reverse thrust within 30 ms, and the landing ends disarmed."""
    cfg = config(reflex={"arm_height_m": 2.0})
    scenario = {
        "faults": [
            {"kind": "rangefinder_spike", "start": SPIKE_T, "end": SPIKE_T + SPIKE_S, "value": FALSE_RANGE_M}
        ]
    }
    with Rig(slope_deg=0.0, seed=74, autopilot=autopilot, scenario=scenario) as rig:
        p, _ = rig.plan(cfg)
        flight, armed, texts, ctx = land_from_over_the_roof(
            rig, p, cfg, SPIKE_T - 1.0, "the spike", autopilot
        )
    cut = flight.time_of("CUT")
    c = flight.contact
    stops = flight.track.event_times("EV_STOP", flight.t_start)
    rvt = flight.track.event_times("EV_RVT", flight.t_start)
    print(f"cut {cut}, motors stopped {stops[:1]}, contact {c}, reverse thrust {rvt[:1]}")
    assert cut is not None and SPIKE_T < cut < SPIKE_T + SPIKE_S, ctx  # the spike made the cut
    assert c is not None, ctx
    assert stops and stops[0] < c["t"] - 0.3, (stops, c, ctx)  # cut well above the roof: a fall
    assert not any("no impact seen" in t or "false cut" in t for t in texts), ctx
    assert rvt and 0 <= rvt[0] - c["t"] < 0.03, (rvt, c, ctx)
    assert flight.end == "LANDED" and not armed, ctx


def test_a_script_failed_in_the_armed_descent_stops_the_landing_in_the_air(autopilot: str, tmp_path) -> None:
    """Raised in ARMED: FAULT, the script climbs the vehicle itself. The companion stops the
    landing (ABORTED, "script fault"), its climb setpoint and LOITER first, the script's climb
    kept (no ABORT) until the vehicle climbs or holds: the vehicle ends armed in LOITER, clear of
    the roof, and the script never cut."""
    cfg = config(reflex={"arm_height_m": 2.0})
    script = injected_script(tmp_path)
    decode = TRACK_MESSAGES | {"PARAM_VALUE"}
    scenario = roof_scenario(autopilot)  # the pilot's throttle centred in the air: LOITER holds
    with Rig(
        slope_deg=SLOPE_DEG, seed=75, autopilot=autopilot, script=script, decode=decode, scenario=scenario
    ) as rig:
        p, _ = rig.plan(cfg)
        rig.take_off(3.0)
        rig.go_over_roof(2.5)
        set_param(rig, "SCR_USER1", RAISES + ScriptState.ARMED)
        flight = rig.land((p.tau_up, p.tau_down), cfg, timeout_s=60.0, rest_s=2.0)
        rig.wait(2.0, tick=flight.lander.poll)
        x, z = rig.track.pos[-1][1], rig.track.pos[-1][2]
        over, mode, armed = z - rig.surface_z(x), rig.mode(), rig.armed()
        texts = [str(t) for t in rig.link.statustext]
    ctx = " | ".join([autopilot] + [f"{h['to']}: {h['reason']}" for h in flight.history])
    ctx += f" || {over:.2f} m over the roof, mode {mode} || " + " | ".join(texts[-8:])
    print(ctx)
    assert flight.end == "ABORTED" and "script fault" in flight.history[-1]["reason"], ctx
    assert "CUT" not in [h["to"] for h in flight.history], ctx
    assert any("fault in ARMED, climbing" in t for t in texts), ctx
    assert armed and mode == LOITER and over > 1.0, ctx


# ------------------------------------------------------------------ a dropout at the cut height
#: the rangefinder loses its returns at and below this reading (m), just above the 0.30 m cut,
#: from this vehicle time (s) on: after the take-off (ArduCopter refuses to arm on a silent sensor)
DROPOUT_BELOW_M = 0.35
DROPOUT_FROM_S = 70.0


def test_a_rangefinder_dropout_just_above_the_cut_height_still_cuts_before_the_roof(autopilot: str) -> None:
    """The soak's landing 5 (ArduCopter, 23bea36): the range went silent in ARMED 0.35 m over the
    roof and the descent met it under power, as the script cut only on a reading. The script now
    reckons the height on the autopilot's descent from its last reading (contract 7): the motors
    stop before the feet touch, the impact is reversed with no range, and the landing ends
    disarmed."""
    dropout = {"kind": "rangefinder_dropout", "start": DROPOUT_FROM_S, "end": 1e5, "below_m": DROPOUT_BELOW_M}
    scenario = {"faults": [dropout]}
    cfg = config()
    with Rig(slope_deg=20.0, seed=75, autopilot=autopilot, scenario=scenario) as rig:
        p, _ = rig.plan(cfg)
        flight, armed, texts, ctx = land_from_over_the_roof(
            rig, p, cfg, DROPOUT_FROM_S, "the dropout", autopilot
        )
    c = flight.contact
    stops = flight.track.event_times("EV_STOP", flight.t_start)
    rvt = flight.track.event_times("EV_RVT", flight.t_start)
    print(f"motors stopped {stops[:1]}, contact {c}, reverse thrust {rvt[:1]}")
    # the stand-in sends no DISTANCE_SENSOR without data, as ArduCopter (GCS_Common.cpp): the
    # companion sees the range age, not an invalid reading
    armed_t = flight.time_of("ARMED")
    assert not [r for t, r in flight.track.ranges if t > armed_t and r < DROPOUT_BELOW_M - 0.03], ctx
    assert any("reckoned" in t for t in texts), ctx  # the cut came from the reckoning, not a reading
    assert c is not None and stops and stops[0] < c["t"], (stops, c, ctx)  # cut before the feet touch
    assert rvt and 0 <= rvt[0] - c["t"] < 0.05, (rvt, c, ctx)
    assert flight.end == "LANDED" and not armed, ctx
