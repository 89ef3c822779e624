"""Flight safety at the edges (issue 40), flown on both autopilots: the simulated vehicle and real
ArduCopter SITL (``SLOPELANDER_ARDUCOPTER``), each case a vehicle of its own.

- The survey pass over a roof's edge: past the gutter the rangefinder has nothing in range, the
  pass's roof guard has nothing to guard with, and the pass is aborted (back over the spot,
  LOITER) instead of flying on blind at constant height.
"""

from __future__ import annotations

from sitl.rig import Rig, config
from slopelander.controller.slope_estimate import SurfaceTrack
from slopelander.controller.survey import RANGE_LOST_S, measure_slope

LOITER = 5
SPOT_X_M = 5.5  # sitl.rig.OVER_ROOF_X_M, where go_over_roof hovers
GUTTER_X_M = 5.7  # the roof's top edge at x = 3 m (sitl.rig.ROOF_X_M) plus a 2.7 m roof


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
