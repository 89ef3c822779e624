"""The rig's recorder forgets old samples on request and keeps the status texts."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from slopelander_sitl.rig import Track


def test_trim_keeps_only_samples_from_the_given_time_on():
    tr = Track()
    for ms in range(0, 5000, 20):
        tr.listen(mavlink.MAVLink_local_position_ned_message(ms, 1.0, 0.0, -2.0, 0.0, 0.0, 0.0))
        tr.listen(mavlink.MAVLink_distance_sensor_message(ms, 20, 300, 150, 10, 1, 25, 100))
        tr.listen(mavlink.MAVLink_named_value_float_message(ms, b"EV_STOP", ms / 1000.0))
    tr.listen(mavlink.MAVLink_statustext_message(6, b"SL: armed"))
    tr.trim(3.0)
    assert tr.pos[0][0] == 3.0 and tr.pos[-1][0] == 4.98 and len(tr.pos) == 100
    assert len(tr.ranges) == 100 and all(t >= 3.0 for t, _ in tr.ranges)
    assert tr.event_times("EV_STOP") == [ms / 1000.0 for ms in range(3000, 5000, 20)]
    assert tr.statustext == ["SL: armed"]


def test_a_height_plus_the_home_range_is_what_the_rangefinder_reads():
    """The soak compares heights over the roof (counted from home) with range thresholds; it adds
    ``home_range_m``. Standing level on the pad, the vehicle's own rangefinder reads the height
    plus that (the soak once compared the two unadjusted and flagged legs loosened at a range
    height of 0.76-0.84 m as loosened at 0.61-0.69 m)."""
    from slopelander_sitl.rig import Rig

    with Rig(slope_deg=30.0, seed=3) as rig:
        rig.wait(1.0)
        assert rig.track.ranges and rig.track.pos
        assert 0.1 < rig.home_range_m < 0.3
        reads = [r for _, r in rig.track.ranges[-20:]]
        assert abs(sum(reads) / len(reads) - (rig.height() + rig.home_range_m)) < 0.01
