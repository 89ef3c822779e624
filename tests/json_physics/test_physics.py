"""Physics sense in the replies, read as ArduPilot reads them: rest, hover, free fall with the
motors at 1500 us, reverse thrust, the rangefinder over a slope, and the leg board's torques."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slopelander.legs import LegBoard
from slopelander_sitl.json_physics.ardupilot_side import ArduPilotSide
from slopelander_sitl.json_physics.launch import start_json_physics
from slopelander_sitl.legboard.control import BoardControl
from slopelander_sitl.vehicle.launch import start_legboard
from tests.json_physics.conftest import QUIET, alt, climb, fly, hover_pwm, run
from tests.legs.fed_clock import board_time, feed_until_done

#: its tests share one physics server (pad_server): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("json_physics/physics")

G = 9.81


def _down_accel(states: list[dict], frame_rate: int = 1200) -> float:
    """Mean downward acceleration (m/s^2) over the states, from the NED velocity."""
    return (states[-1]["velocity"][2] - states[0]["velocity"][2]) / ((len(states) - 1) / frame_rate)


def test_at_rest_on_the_pad_the_imu_reads_one_g_up(ap: ArduPilotSide) -> None:
    s = run(ap, 0.3, [1525] * 4)[-1]  # 1525 us is inside the ESC's neutral band: stopped
    assert s["imu.accel_body"] == pytest.approx([0.0, 0.0, -G], abs=0.01)
    assert s["imu.gyro"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-4)
    assert s["attitude"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-4)
    assert s["position"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-3)
    assert 0.05 < s["rng_1"] < 0.3  # body origin a leg's height above the pad


def test_hover_output_holds_the_altitude(ap: ArduPilotSide) -> None:
    s = fly(ap, 3.0, 1.0)
    assert alt(s) == pytest.approx(1.0, abs=0.05) and abs(climb(s)) < 0.1
    held = run(ap, 1.0, [hover_pwm()] * 4)  # open loop: nothing corrects
    assert abs(alt(held[-1]) - alt(s)) < 0.1 and abs(climb(held[-1])) < 0.15
    # over the level pad, range and altitude move together
    offsets = [st["rng_1"] - alt(st) for st in held]
    assert max(offsets) - min(offsets) < 0.005


def test_motors_at_1500_fall_at_g(ap: ArduPilotSide) -> None:
    fly(ap, 3.0, 1.5)
    fall = run(ap, 0.5, [1500] * 4)
    late = fall[180:]  # rotors spun down after 0.15 s
    assert _down_accel(late) == pytest.approx(G, abs=0.1)
    acc = np.array([st["imu.accel_body"] for st in late])
    assert np.abs(acc).max() < 0.1  # free fall: no specific force
    assert alt(fall[-1]) < alt(fall[0]) - 0.5


def test_reversed_outputs_push_down(ap: ArduPilotSide) -> None:
    assert alt(fly(ap, 4.0, 2.0)) > 1.9
    push = run(ap, 0.5, [1000] * 4)  # full reverse: stop, reversal delay, then thrust downwards
    late = push[-100:]
    assert alt(late[-1]) > 0.3  # still in the air
    assert min(st["imu.accel_body"][2] for st in late) > 0.5 * G  # specific force points down
    assert _down_accel(late) > 1.5 * G
    assert min(st["imu.accel_body"][2] for st in push[:60]) < -0.5 * G  # still forward at first


def test_rangefinder_over_a_slope_matches_the_geometry() -> None:
    """Level flight and pitched flight over a 30 deg roof: the beam along the body's down axis
    from the reported position and pitch meets the roof plane where rng_1 says."""
    slope = math.radians(30)
    srv = start_json_physics(scenario={**QUIET, "start_on": "roof", "slope_deg": 30})
    ap = ArduPilotSide(srv.port)
    try:
        on_roof = run(ap, 0.3, [1525] * 4)[-1]
        assert on_roof["attitude"][1] == pytest.approx(-slope, abs=0.03)  # standing on the roof
        fly(ap, 2.0, 1.0)
        states = []
        for pitch in (0.15, -0.15, 0.0, 0.15):
            for _ in range(500):
                states.append(dict(fly(ap, 1 / 1200, 1.0, pitch)))
    finally:
        ap.close()
        srv.stop()
    pitches = [st["attitude"][1] for st in states]
    assert max(pitches) > 0.1 and min(pitches) < -0.1
    # ray (x + r sin p, z - r cos p) on the plane z = c - x tan(slope) for one constant c
    c = [
        st["rng_1"] * (math.cos(p) - math.sin(p) * math.tan(slope))
        - (alt(st) + st["position"][0] * math.tan(slope))
        for st, p in zip(states, pitches, strict=True)
    ]
    assert max(c) - min(c) < 0.002
    assert max(st["rng_1"] for st in states) - min(st["rng_1"] for st in states) > 0.5  # it moved


def test_the_leg_boards_torques_act_on_the_ground() -> None:
    """Clamped legs carry the vehicle on the pad; loosened over the leg board's serial link, they
    fold under it, and the board is told the joints' new angles.

    The board runs on a fed clock (tests/legs/fed_clock.py says why): on the wall clock a loaded
    machine read 21 deg, its spring having moved the legs after the physics' last write."""
    lb = start_legboard(clock="external")
    try:
        with BoardControl(lb.control) as ctl:
            board = LegBoard.open(lb.pty)
            board_time(board, ctl)
            try:
                t = feed_until_done(board, ctl, board.start_torques({leg: 2.3 for leg in range(4)}), 30.0)
                srv = start_json_physics(scenario=QUIET, legs=lb.control)
                ap = ArduPilotSide(srv.port)
                try:
                    clamped = run(ap, 1.0, [1525] * 4)
                    feed_until_done(board, ctl, board.start_loosen(), t + 30.0)
                    loose = run(ap, 1.5, [1525] * 4)
                finally:
                    ap.close()
                    srv.stop()
            finally:
                board.close()
            angles = [float(leg["angle_deg"]) for leg in ctl.state()["legs"]]
    finally:
        lb.stop()
    assert abs(alt(clamped[-1]) - alt(clamped[0])) < 0.005
    assert alt(loose[-1]) < alt(clamped[-1]) - 0.05
    assert loose[-1]["rng_1"] < clamped[-1]["rng_1"] - 0.05
    assert max(angles) < 20.0, angles  # folded from the clamped ~37 deg


def test_rangefinder_from_the_pad_onto_the_roof(ap: ArduPilotSide) -> None:
    """Flying north from the pad over the roof's edge (3 m north, 0.5 m up, 20 deg down toward
    north): rng_1 follows the pad, then the roof plane, from the reported position and pitch."""
    rest = run(ap, 0.2, [1525] * 4)[-1]["rng_1"]  # level on the pad: the body's height above it
    fly(ap, 3.0, 1.5)
    states = []
    for pitch, seconds in ((-0.12, 1.9), (0.12, 1.0), (0.0, 1.0)):
        for _ in range(round(seconds * 1200)):
            states.append(dict(fly(ap, 1 / 1200, 1.5, pitch)))
    slope = math.radians(20)
    errors = []
    for st in states:
        north, z, p = st["position"][0], alt(st) + rest, st["attitude"][1]
        if abs(north - 3.0) < 0.4:
            # the beam has a width (2 deg, docs/simulated-vehicle.md): while its footprint straddles
            # the edge it reads a mean of the two surfaces, not one point's range
            continue
        if north < 3.0:
            expected = z / math.cos(p)
        else:
            expected = (z - 0.5 + (north - 3.0) * math.tan(slope)) / (
                math.cos(p) - math.sin(p) * math.tan(slope)
            )
        errors.append(abs(st["rng_1"] - expected))
    norths = [st["position"][0] for st in states]
    assert min(norths) < 1.0 and max(norths) > 3.5  # it crossed the edge
    assert max(errors) < 0.002
    over_roof = [st["rng_1"] for st in states if st["position"][0] > 3.2]
    assert over_roof and min(over_roof) < min(st["rng_1"] for st in states if st["position"][0] < 2.8)


def test_scenario_faults_reach_the_replies() -> None:
    """A rangefinder dropout is a NaN rng_1 (ArduPilot's "no data": a negative one reads 0 m, "too
    close", AP_RangeFinder_SITL.cpp); an IMU spike adds to
    the body-z specific force; both only while the fault lasts."""
    faults = [
        {"kind": "rangefinder_dropout", "start": 0.1, "end": 0.2},
        {"kind": "imu_spike", "start": 0.3, "end": 0.35, "value": 30.0},
    ]
    srv = start_json_physics(scenario={**QUIET, "faults": faults})
    ap = ArduPilotSide(srv.port)
    try:
        states = run(ap, 0.5, [1525] * 4)
    finally:
        ap.close()
        srv.stop()

    def during(a: float, b: float) -> list[dict]:
        return [st for st in states if a + 0.002 < st["timestamp"] < b - 0.002]

    assert during(0.1, 0.2) and all(math.isnan(st["rng_1"]) for st in during(0.1, 0.2))
    assert all(0.05 < st["rng_1"] < 0.3 for st in during(0.0, 0.1) + during(0.2, 0.5))
    assert all(st["imu.accel_body"][2] == pytest.approx(-G + 30.0, abs=0.01) for st in during(0.3, 0.35))
    assert all(st["imu.accel_body"][2] == pytest.approx(-G, abs=0.01) for st in during(0.36, 0.5))


def test_the_scenarios_wind_pushes_the_vehicle() -> None:
    """A steady 3 N northward wind on a level hover: the vehicle accelerates north at F/m and
    the IMU feels it (a non-gravitational force) along body x."""
    from slopelander.model.landing import Model

    p = Model.default().params
    mass = p["body_mass"] + 2 * p["leg_mass"]
    srv = start_json_physics(scenario={**QUIET, "wind": {"steady": {"fx_n": 3.0, "fz_n": 0.0}}})
    ap = ArduPilotSide(srv.port)
    try:
        run(ap, 0.2, [1525] * 4)  # on the pad: friction holds it
        fly(ap, 2.0, 1.0)
        states = [dict(fly(ap, 1 / 1200, 1.0)) for _ in range(600)]
    finally:
        ap.close()
        srv.stop()
    vn = [st["velocity"][0] for st in states]
    assert (vn[-1] - vn[0]) / 0.5 == pytest.approx(3.0 / mass, rel=0.05)
    assert states[-1]["imu.accel_body"][0] == pytest.approx(3.0 / mass, rel=0.05)


def test_outputs_without_a_pulse_leave_the_rotors_stopped(ap: ArduPilotSide) -> None:
    """ArduPilot reports 0 for outputs it does not drive: no pulse, so the ESCs stop (the vehicle
    falls at g) instead of reading it as full reverse (it would fall at about 2 g)."""
    assert alt(fly(ap, 4.0, 2.0)) > 1.9
    fall = run(ap, 0.5, [0, 0, 0, 0])
    assert _down_accel(fall[180:]) == pytest.approx(G, abs=0.1)
    assert np.abs(np.array([st["imu.accel_body"] for st in fall[180:]])).max() < 0.1


def test_arducopters_yaw_torque_turns_the_vehicle_clockwise_and_the_reply_says_so() -> None:
    """ArduCopter turns a quad X clockwise (seen from above, positive yaw) by adding thrust to
    motors 1 and 2 (counter-clockwise props) and taking as much from 3 and 4 (it mixes in thrust):
    so does the physics, in the air, and the pairs' thrust is kept (the vertical speed changes as
    with four equal motors: the mean of the pairs' commands lost 4 % and sank the vehicle). The
    reply's yaw and body yaw rate follow; on the pad the same outputs turn nothing."""
    from slopelander_sitl.json_physics.physics import JsonPhysics
    from slopelander_sitl.json_physics.protocol import encode_reply
    from slopelander_sitl.vehicle import esc
    from slopelander_sitl.vehicle.scenario import scenario_from_dict

    quiet = {"accel": 0.0, "gyro": 0.0, "range": 0.0}
    scn = scenario_from_dict({"slope_deg": 20.0, "seed": 5, "noise": quiet})
    hi, lo = 1870, 1808  # what ArduCopter sends (whole microseconds) to turn near hover
    u_hi, u_lo = esc.pwm_to_command(hi), esc.pwm_to_command(lo)
    u0 = math.sqrt(0.5 * (u_hi * u_hi + u_lo * u_lo))  # four equal motors with the same thrust
    turning = (hi, hi, lo, lo)
    on_pad = JsonPhysics(scn)
    for _ in range(800):
        on_pad.step(1 / 800, turning)
    assert on_pad.fdm().attitude[2] == 0.0  # the feet hold it
    dv = {}
    for pwm in ((esc.NEUTRAL_US + 500.0 * u0,) * 4, turning):
        physics = JsonPhysics(scn)
        for _ in range(2400):  # climb clear of the pad
            physics.step(1 / 800, (1900,) * 4)
        v0 = physics.fdm().velocity[2]
        for _ in range(800):
            physics.step(1 / 800, pwm)
        f = physics.fdm()
        dv[pwm] = f.velocity[2] - v0
    assert f.attitude[2] > math.radians(5.0), f.attitude  # clockwise
    assert f.gyro[2] > 0.1, f.gyro
    assert physics.reply() == encode_reply(f)
    straight, turn = dv.values()
    assert turn == pytest.approx(straight, abs=0.002), dv
