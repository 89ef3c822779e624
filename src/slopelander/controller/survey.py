"""Measuring the slope before PRESET: the estimate from what the rangefinder has seen near the
spot, and when that is too little, a short survey pass the companion flies itself.

The pass: in GUIDED, armed, at the hover's height (NED down held), a position target moving at
``slope.survey_speed_mps`` from the spot ``slope.survey_length_m``/2 south, then the whole length
north, then back to the spot, where the vehicle must come to rest before the landing starts; it
turns back early where the range falls below ``slope.survey_min_range_m`` (the roof rising). It
is flown before the state machine starts because the preset (PRESET, the first state) is chosen
from the slope. A vehicle not in GUIDED or not armed is not flown: the estimate is refused.
See docs/slope-estimate.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from slopelander.controller.link import Link, mavlink
from slopelander.controller.slope_estimate import EstimateSettings, SlopeEstimate, SurfaceTrack, estimate

#: position-only setpoint (velocity, acceleration and yaw ignored), as ArduCopter's GUIDED reads it
POSITION_MASK = 0x0DF8
GUIDED = 4
SEND_HZ = 10.0
#: at the spot again: within this (m) and slower than this (m/s)
AT_SPOT_M = 0.15
AT_REST_MPS = 0.1
#: a range reading older than this (s of vehicle time) does not guard the pass
RANGE_FRESH_S = 0.3
#: the range's fall rate is read over this much of the newest readings (s)
RATE_WINDOW_S = 0.25
#: a turned-back vehicle brakes for about this long (s): its range falls on meanwhile (the
#: simulated vehicle at 0.35 m/s: 0.15 m in 0.5 s)
STOP_LOOKAHEAD_S = 0.6


def survey_refusal(link: Link) -> str | None:
    """Why the companion may not fly the pass now, or None."""
    hb = link.last.get("HEARTBEAT")
    if link.lost or hb is None:
        return "no link to the autopilot" + (f" ({link.reboot_note})" if link.rebooted else "")
    if hb.custom_mode != GUIDED:
        return f"mode number {hb.custom_mode}, GUIDED needed to fly the survey pass"
    if not hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
        return "vehicle not armed: no survey pass"
    return None


def measure_slope(
    link: Link,
    cfg,
    track: SurfaceTrack,
    *,
    fly: bool = True,
    tick: Callable[[], None] | None = None,
    note: Callable[[str], None] = print,
    wall_s: float = 300.0,
) -> tuple[SlopeEstimate, float]:
    """The slope at the spot under the vehicle now, and the vehicle seconds a survey pass took (0
    when none was flown). ``tick`` polls the link (and whatever else must stay alive: the leg
    board) while the pass is flown; by default ``link.poll``."""
    st = EstimateSettings.from_config(cfg)
    tick = tick or link.poll
    end = time.monotonic() + 5.0  # the streams were just asked for: a moment for the first position
    while track.position() is None and time.monotonic() < end:
        tick()
        time.sleep(0.002)
    pos = track.position()
    if pos is None:
        est = estimate([], 0.0, st)
        est.refusal = "no position (LOCAL_POSITION_NED) to place the rangefinder's points"
        return est, 0.0
    spot_n, spot_e, spot_d = pos
    est = estimate(track.points(), spot_n, st)
    if est.ok or not est.needs_survey or not fly:
        return est, 0.0
    why = survey_refusal(link)
    if why is not None:
        est.refusal = f"{est.refusal}; {why}"
        return est, 0.0
    note(f"survey: {est.refusal}; flying {cfg['slope.survey_length_m']:g} m along north over the spot")
    t0 = link.clock.now()
    done = _fly_pass(link, cfg, track, (spot_n, spot_e, spot_d), tick, wall_s, note)
    took = link.clock.now() - t0
    est = estimate(track.points(), spot_n, st)
    if done is not None:
        est.refusal = f"survey pass not finished: {done}"
    return est, took


def low_range(track: SurfaceTrack, now: float, min_range_m: float) -> float | None:
    """The range the vehicle will read once stopped, if the newest reading is fresh (within
    RANGE_FRESH_S of vehicle time ``now``) and that range is below ``min_range_m``, else None.

    Once stopped: the newest reading less its fall over STOP_LOOKAHEAD_S at the rate of the
    last RATE_WINDOW_S of readings (a vehicle turned back keeps going while it brakes, and over
    a 60 deg roof the range falls 0.7 m/s at the pass's 0.4 m/s)."""
    if not track.ranges:
        return None
    t, r = track.ranges[-1]
    if abs(now - t) > RANGE_FRESH_S:
        return None
    fall = 0.0
    for t_old, r_old in reversed(track.ranges):
        if t - t_old >= RATE_WINDOW_S:
            fall = max(0.0, (r_old - r) / (t - t_old))
            break
    ahead = r - fall * STOP_LOOKAHEAD_S
    return ahead if ahead < min_range_m else None


def _fly_pass(
    link: Link, cfg, track: SurfaceTrack, spot, tick, wall_s: float, note: Callable[[str], None] = print
) -> str | None:
    """Fly the pass; None when the vehicle is back at rest over the spot, else why not.

    The target moves at the survey speed toward each end in turn, then back to the spot. The
    pass holds its height while the surface may rise under it: where the range reads below
    ``slope.survey_min_range_m`` (or will, by the time a vehicle turned now has stopped) the
    target turns back at once (uphill on a steep roof: at
    60 deg, 1 m of the pass rises the roof 1.7 m, into a vehicle hovering 1 m over the spot)."""
    n0, e0, d0 = spot
    half = cfg["slope.survey_length_m"] / 2
    v = cfg["slope.survey_speed_mps"]
    min_range = cfg["slope.survey_min_range_m"]
    goals = [n0 - half, n0 + half, n0]
    leg = 0
    target = n0
    t0 = link.clock.now()
    last_t = t0
    limit = cfg["slope.survey_timeout_s"]
    end_wall = time.monotonic() + wall_s
    last_sent = -1.0
    while True:
        tick()
        why = survey_refusal(link)
        if why is not None:
            return why
        now = link.clock.now()
        el = now - t0
        if el > limit or time.monotonic() > end_wall:
            _send(link, n0, e0, d0)
            return f"not back over the spot within {limit:g} s"
        step = v * max(0.0, now - last_t)
        last_t = now
        if leg < len(goals):
            goal = goals[leg]
            if abs(goal - target) <= step:
                target = goal
                leg += 1
            else:
                target += step if goal > target else -step
        here = link.last.get("LOCAL_POSITION_NED")
        north = float(here.x) if here is not None else target
        # guarded: going out south, and north of the spot going out north (between the south
        # end and the spot the vehicle has just flown; a turn there would undo the pass)
        guarded = leg == 0 or (leg == 1 and north >= n0)
        r = low_range(track, now, min_range) if guarded else None
        if r is not None:  # the surface rises ahead
            target = north  # the target leads the vehicle: turn where the vehicle is
            note(f"survey: range falling to {r:.2f} m {target - n0:+.2f} m north of the spot: turned back")
            leg += 1
            last_sent = -1.0  # the new direction goes out now
        if now - last_sent >= 1.0 / SEND_HZ or now < last_sent:
            _send(link, target, e0, d0)
            last_sent = now
        if leg >= len(goals):
            p = link.last.get("LOCAL_POSITION_NED")
            if (
                p is not None
                and abs(p.x - n0) < AT_SPOT_M
                and abs(p.vx) < AT_REST_MPS
                and abs(p.vy) < AT_REST_MPS
                and abs(p.vz) < AT_REST_MPS
            ):
                return None
        time.sleep(0.001)


def _send(link: Link, n: float, e: float, d: float) -> None:
    info = link.info
    if info is None:
        return
    link.conn.mav.set_position_target_local_ned_send(
        int(link.clock.now() * 1000) & 0xFFFFFFFF,
        info.system,
        info.component,
        mavlink.MAV_FRAME_LOCAL_NED,
        POSITION_MASK,
        float(n),
        float(e),
        float(d),
        0,
        0,
        0,
        0,
        0,
        0,
        0,
        0,
    )
