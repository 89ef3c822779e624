"""The impact rule on real ArduCopter with its accelerometer vibrating (issue 40, finding 6: the
rule fired reverse thrust 24-26 cm up at a filtered 6-8.5 m/s² of 15-70 Hz on the script bench).

ArduPilot's own IMU simulation adds the vibration: a sine at ``SIM_VIB_FREQ_X/Y/Z`` Hz of
``SIM_ACC1_RND`` m/s² on each axis while its throttle is above ``SIM_INS_THR_MIN``
(``AP_InertialSensor_SITL::generate_accel``, libraries/AP_InertialSensor/AP_InertialSensor_SITL.cpp),
before the INS_ACCEL_FILTER (20 Hz) the script reads through. Behind the JSON physics that
throttle stays 0, so the threshold is set below it once the vehicle flies (at boot the first
IMU's vibration alone fails the pre-arm "Accels inconsistent"): the vibration then lasts through
the cut and on the roof, harsher than rotors that stop. Measured: RAW_IMU's z swings 503 mG RMS
with it, 1.1 mG without; at 30 m/s² the rule reversed 33-62 ms before the contact, and this test
failed as it should. At 15 Hz and 8 m/s² the filtered
signal swings about 7 m/s², inside the bench case; the landing uses the shipped impact threshold
(20 m/s²). The simulated vehicle has no such model: the rule's full spectrum, with the rotors
ringing down after the cut, is held on the script bench (tests/firmware/test_script_vibration.py)."""

from __future__ import annotations

import statistics

import pytest
from pymavlink.dialects.v20 import common as mavlink

from slopelander_sitl.rig import Rig, config
from tests.flights.conftest import autopilot_available
from tests.flights.test_landings_on_both_autopilots import PRESET
from tests.flights.test_takeoff_target import ON_ARDUCOPTER

VIBRATION = {"SIM_VIB_FREQ_X": 15.0, "SIM_VIB_FREQ_Y": 15.0, "SIM_VIB_FREQ_Z": 15.0, "SIM_ACC1_RND": 8.0}


@pytest.mark.parametrize(
    "slope_deg",
    [
        pytest.param(
            0.0,
            marks=[
                *ON_ARDUCOPTER,
                pytest.mark.xfail(
                    reason="a known limit: SITL's vibration goes on at full strength with the motors "
                    "stopped (harsher than rotors ringing down), and on the flat roof the rule fired 5 "
                    "and 16 ms before the contact (1-2.4 cm up) in 2 of 4 runs",
                    strict=False,
                ),
            ],
        ),
        pytest.param(30.0, marks=ON_ARDUCOPTER),
    ],
)
def test_a_vibrating_accelerometer_reverses_only_at_the_contact_on_arducopter(slope_deg: float) -> None:
    autopilot = autopilot_available("ardupilot")
    cfg = config()  # the shipped impact threshold and cut height
    with Rig(slope_deg=slope_deg, seed=61, autopilot=autopilot, arducopter_params=VIBRATION) as rig:
        rig.take_off(3.0)
        rig.go_over_roof(2.5)
        rig.link.conn.mav.param_set_send(1, 1, b"SIM_INS_THR_MIN", -1.0, mavlink.MAV_PARAM_TYPE_REAL32)
        rig.wait(1.0)
        n0 = rig.link.received.get("RAW_IMU", 0)
        rig.wait(1.0)
        z = [m.zacc for m in rig.link.since("RAW_IMU", n0)[0]]
        assert statistics.pstdev(z) > 300, "the accelerometer does not vibrate (mG RMS)"
        flight = rig.land(PRESET, cfg, timeout_s=90.0, rest_s=3.0)
    ctx = " | ".join([f"{slope_deg:g} deg"] + [f"{h['to']}: {h['reason']}" for h in flight.history])
    c = flight.contact
    assert c is not None, ctx
    stops = flight.track.event_times("EV_STOP", flight.t_start)
    rvt = flight.track.event_times("EV_RVT", flight.t_start)
    assert stops and stops[0] < c["t"], (stops, c, ctx)
    assert rvt and c["t"] - 0.001 <= rvt[0] < c["t"] + 0.03, (rvt, c, ctx)  # at the contact, not in the air
    # the vibration goes on after the motors stopped, so the vehicle never reads still: the
    # reverse thrust runs to its bound and the landing waits in SETTLED, motors held
    assert flight.end in ("LANDED", "SETTLED"), ctx
