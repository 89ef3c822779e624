"""The rules module on its own: each rule's edges as ArduCopter's source draws them."""

from __future__ import annotations

import math

from slopelander_sitl.vehicle import arducopter_rules as r
from slopelander_sitl.vehicle import modes


def test_force_magics_differ_for_arm_and_disarm():
    assert r.arm_disarm_request(1, 2989) == ("arm", False)
    assert r.arm_disarm_request(1, 21196) == ("arm", True)  # not a force for arming
    assert r.arm_disarm_request(0, 21196) == ("disarm", False)
    assert r.arm_disarm_request(0, 2989) == ("disarm", True)
    assert r.arm_disarm_request(0.5, 0)[0] == "unsupported"


def test_ground_station_disarm_waits_for_the_land_detector_the_script_does_not():
    assert r.disarm_refused(r.GCS, checks=True, land_complete=False, manual_throttle=False)
    assert not r.disarm_refused(r.GCS, checks=True, land_complete=True, manual_throttle=False)
    assert not r.disarm_refused(r.GCS, checks=False, land_complete=False, manual_throttle=False)
    assert not r.disarm_refused(r.SCRIPTING, checks=True, land_complete=False, manual_throttle=False)


def test_arming_in_guided_from_the_ground_station_needs_the_throttle_down():
    """AP_Arming_Copter skips its "Throttle too high" for GCS arming in GUIDED, but
    AP_Arming::rc_arm_checks (RC_OPTIONS bit 5, the default) still wants the stick at the bottom."""

    def why(stick_up: bool, rc_options: int = 32, method: str = r.GCS, arming_check: float = 1) -> str | None:
        return r.arming_failure(
            modes.GUIDED, method, False, 0.0, 3000, arming_check, False, stick_up, rc_options
        )

    assert why(False) is None
    assert why(True) == "Arm: Throttle (RC3) is not neutral"
    assert why(True, method=r.SCRIPTING) == "Arm: Throttle (RC3) is not neutral"
    assert why(True, rc_options=0) is None  # the check switched off
    assert why(True, arming_check=0) is None  # no checks at all


def test_rc_overrides_only_from_the_ground_station():
    assert r.rc_override_accepted(255)
    assert not r.rc_override_accepted(1)  # the companion's (and the vehicle's) own id
    assert r.rc_override_accepted(7, gcs_sysid=7)


def test_sitl_rangefinder_value_meaning():
    assert r.sitl_rangefinder(-1.0, 0.1, 3.0) == (0.0, r.OUT_OF_RANGE_LOW)  # too close, not a dropout
    assert r.sitl_rangefinder(math.nan, 0.1, 3.0)[1] == r.NO_DATA
    assert r.sitl_rangefinder(math.inf, 0.1, 3.0)[1] == r.NO_DATA
    assert r.sitl_rangefinder(5.0, 0.1, 3.0) == (5.0, r.OUT_OF_RANGE_HIGH)
    assert r.sitl_rangefinder(0.05, 0.1, 3.0) == (0.05, r.OUT_OF_RANGE_LOW)
    assert r.sitl_rangefinder(1.0, 0.1, 3.0) == (1.0, r.GOOD)


def test_rangefinder_runs_at_20_hz_of_a_400_hz_loop():
    assert sum(r.rangefinder_due(i, 400) for i in range(400)) == 20


def _landing(**kw) -> r.LandInputs:
    base = dict(
        armed=True,
        throttle_at_lower_limit=True,
        angle_target_deg=0.0,
        angle_error_deg=0.0,
        accel_ef=(0.0, 0.0),
        climb_rate=0.0,
        descent_demanded=True,
        landing_mode=False,
        rangefinder_alt_ok=True,
        rangefinder_alt_filt_m=0.2,
    )
    base.update(kw)
    return r.LandInputs(**base)


def _ticks_to_land(x: r.LandInputs, limit: int = 2000) -> int | None:
    d = r.LandDetector(400)
    d.set_landed(False)
    for i in range(limit):
        d.update(1 / 400, x)
        if d.landed:
            return i + 1
    return None


def test_land_detector_fires_after_one_second_of_every_condition():
    n = _ticks_to_land(_landing())
    assert n is not None and 400 <= n <= 402


def test_land_detector_never_fires_when_a_condition_fails():
    for bad in (
        dict(angle_error_deg=31.0),  # a slope forcing the airframe's attitude
        dict(angle_target_deg=16.0),
        dict(throttle_at_lower_limit=False),
        dict(descent_demanded=False),  # the companion stopped asking for descent
        dict(climb_rate=-1.1),
        dict(accel_ef=(1.5, 0.0)),
        dict(rangefinder_alt_filt_m=2.5),
    ):
        assert _ticks_to_land(_landing(**bad)) is None, bad
    assert _ticks_to_land(_landing(rangefinder_alt_ok=False, rangefinder_alt_filt_m=2.5)) is not None


def test_takeoff_refusals_and_height_frames():
    kw = dict(
        param3=0.0,
        height_above_home_m=0.0,
        rangefinder_healthy=True,
        rangefinder_alt_m=0.15,
        rangefinder_max_m=3.0,
        wpnav_rfnd_use=1,
    )
    assert r.takeoff(modes.GUIDED, False, True, 2.0, **kw) is None  # disarmed
    assert r.takeoff(modes.GUIDED, True, False, 2.0, **kw) is None  # already flying
    assert r.takeoff(modes.STABILIZE, True, True, 2.0, **kw) is None
    assert r.takeoff(modes.ALT_HOLD, True, True, 2.0, **kw) is None  # must navigate (param3 0)
    assert r.takeoff(modes.GUIDED, True, True, 0.0, **kw) is None  # not above where it is
    assert r.takeoff(modes.GUIDED, True, True, 2.0, **kw) == r.Takeoff(2.0, above_terrain=True)
    assert r.takeoff(modes.GUIDED, True, True, 3.0, **kw) == r.Takeoff(3.0, above_terrain=False)
    kw["rangefinder_healthy"] = False
    assert r.takeoff(modes.GUIDED, True, True, 2.0, **kw) == r.Takeoff(2.0, above_terrain=False)


def test_message_interval_ceiling_as_measured_on_arducopter():
    assert r.message_interval_result(5000, 400, True) == r.ACCEPTED  # 200 Hz
    assert r.message_interval_result(3000, 400, True) == r.ACCEPTED  # 333 Hz
    assert r.message_interval_result(2500, 400, True) == r.DENIED  # 400 Hz
    assert r.message_interval_result(2500, 800, True) == r.ACCEPTED
    assert r.message_interval_result(-1, 400, True) == r.ACCEPTED
    assert r.message_interval_result(5000, 400, False) == r.DENIED
