"""Measuring the slope before PRESET: the plane from what the rangefinder has seen near the spot,
and when that is too little, a short survey pass the companion flies itself; then the vehicle
turned to face the fall line, the way the planar legs and the lookup table land.

The pass: in GUIDED, armed, at the hover's height (NED down held), two legs through the spot, the
first along the vehicle's heading, the second along the heading turned 90 deg to its right. Each
leg is flown facing its way: the vehicle turns on the spot to the leg's heading, then a position
target moves at ``slope.survey_speed_mps`` from the spot ``slope.survey_length_m``/2 back, then
the whole length ahead, then back to the spot, where the vehicle must come to rest. A leg turns
back early where the range falls below ``slope.survey_min_range_m`` (the roof rising). Every
setpoint carries the heading (SET_POSITION_TARGET_LOCAL_NED with its yaw): ArduCopter's GUIDED
resets a heading given any other way (MAV_CMD_CONDITION_YAW) at the next setpoint without one, and
left to its default (WP_YAW_BEHAVIOR) it may turn the vehicle to face its way of travel.

Then the turn: facing the fall line (the plane's steepest way down, when the plane is at least
``slope.max_cross_deg`` steep; else back to the heading the pass started from), held over the spot
until the slope across the heading is within half of ``slope.max_cross_deg`` and the vehicle is at
rest. The estimate is the plane's along the heading the vehicle then has (ATTITUDE's yaw), refused
when the slope across it exceeds ``slope.max_cross_deg``. All of it is flown before the state
machine starts because the preset (PRESET, the first state) is chosen from the slope. A vehicle not
in GUIDED or not armed is not flown: the estimate is refused. See docs/slope-estimate.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from slopelander.controller.link import Link, mavlink
from slopelander.controller.slope_estimate import (
    EstimateSettings,
    PlaneEstimate,
    SlopeEstimate,
    SurfaceTrack,
    az_text,
    cross_refusal,
    estimate_plane,
    wrap_deg,
)

#: position and yaw setpoint (velocity, acceleration and yaw rate ignored), as ArduCopter's GUIDED
#: reads it: its yaw sets the heading (ModeGuided::set_yaw_state)
POSITION_YAW_MASK = 0x09F8
#: the same without the yaw (bit 10 set): the heading left to the autopilot
POSITION_MASK = 0x0DF8
GUIDED = 4
SEND_HZ = 10.0
#: at the spot again: within this (m) along the leg, within ACROSS_SPOT_M across it, and slower
#: than AT_REST_MPS (m/s). Across a leg the pass's geometry needs less (the legs cross within it
#: of the spot, and each leg's sides are checked on its own points); a planar simulator cannot
#: move across its heading at all, so what a turn left across stays there
AT_SPOT_M = 0.15
ACROSS_SPOT_M = 0.3
AT_REST_MPS = 0.1
#: a leg is flown once the heading is within this of the leg's (deg)
LEG_HEADING_DEG = 3.0
#: the second leg's heading from the first's (deg, clockwise)
SECOND_LEG_DEG = 90.0
#: a range reading older than this (s of vehicle time) does not guard the pass
RANGE_FRESH_S = 0.3
#: the range's fall rate is read over this much of the newest readings (s)
RATE_WINDOW_S = 0.25
#: a turned-back vehicle brakes for about this long (s): its range falls on meanwhile (the
#: simulated vehicle at 0.35 m/s: 0.15 m in 0.5 s)
STOP_LOOKAHEAD_S = 0.6
#: no in-range reading for longer than this (s of vehicle time) while a leg flies out aborts the
#: pass: the roof guard (:func:`low_range`) stops guarding at RANGE_FRESH_S, and a rangefinder that
#: lost the surface (weak returns off a steep roof, a roof risen nearer than the sensor's minimum,
#: an edge) must not let the pass fly on blind at constant height. Six of ArduCopter's 20 Hz samples
RANGE_LOST_S = RANGE_FRESH_S
#: LOITER's custom mode number (ArduCopter)
LOITER = 5


def survey_refusal(link: Link) -> str | None:
    """Why the companion may not fly the pass now, or None."""
    hb = link.last.get("HEARTBEAT")
    if link.lost or hb is None:
        why = link.reboot_note if link.rebooted else link.lost_why
        return "no link to the autopilot" + (f" ({why})" if why else "")
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
    """The slope at the spot under the vehicle now, along the heading it lands with, and the
    vehicle seconds the survey pass and the turns took (0 when none was flown). ``tick`` polls the
    link (and whatever else must stay alive: the leg board) meanwhile; by default ``link.poll``.
    ``fly=False``: nothing is flown, the plane is read along the heading there is."""
    st = EstimateSettings.from_config(cfg)
    tick = tick or link.poll
    end = time.monotonic() + 5.0  # the streams were just asked for: a moment for the first position
    while (track.position() is None or track.heading_deg() is None) and time.monotonic() < end:
        tick()
        time.sleep(0.002)
    pos, heading = track.position(), track.heading_deg()
    if pos is None or heading is None:
        est = estimate_plane([], (0.0, 0.0), st).along(heading or 0.0)
        missing = "LOCAL_POSITION_NED" if pos is None else "ATTITUDE"
        est.refusal = f"no {missing} to place the rangefinder's points"
        return est, 0.0
    spot = pos
    plane = estimate_plane(track.surface_points(), spot[:2], st)
    if not fly:
        return _along(plane, heading, cfg), 0.0
    t0 = link.clock.now()
    if not plane.ok:
        why = survey_refusal(link) if plane.needs_survey else None
        if not plane.needs_survey or why is not None:
            est = plane.along(heading)
            if why is not None:
                est.refusal = f"{est.refusal}; {why}"
            return est, 0.0
        length = cfg["slope.survey_length_m"]
        note(
            f"survey: {plane.refusal}; flying {length:g} m toward {az_text(heading)} and "
            f"{length:g} m toward {az_text(heading + SECOND_LEG_DEG)} over the spot"
        )
        for leg_heading in (heading, heading + SECOND_LEG_DEG):
            done = _turn(link, cfg, track, spot, leg_heading, None, tick, wall_s, note)
            done = done or _fly_leg(link, cfg, track, spot, leg_heading % 360.0, tick, wall_s, note)
            if done is not None:
                est = estimate_plane(track.surface_points(), spot[:2], st).along(track.heading_deg())
                est.refusal = f"survey pass not finished: {done}"
                if done.startswith(DROPOUT):
                    _loiter(link, spot, track.heading_deg())
                    note("survey: pass aborted on the rangefinder dropout; LOITER asked over the spot")
                return est, link.clock.now() - t0
        plane = estimate_plane(track.surface_points(), spot[:2], st)
        if not plane.ok:
            return plane.along(track.heading_deg()), link.clock.now() - t0
    if plane.plane_slope_deg >= cfg["slope.max_cross_deg"]:  # face the fall line
        done = _turn(link, cfg, track, spot, plane.fall_azimuth_deg, plane, tick, wall_s, note)
    else:  # no fall line worth the name: back to the heading the pilot gave it
        done = _turn(link, cfg, track, spot, heading, None, tick, wall_s, note)
    took = link.clock.now() - t0
    est = _along(plane, track.heading_deg(), cfg)
    if done is not None and est.ok and est.cross_deg is not None:
        why = cross_refusal(est, cfg["slope.max_cross_deg"])
        if why is not None:
            est.refusal = f"{why} (the turn: {done})"
    return est, took


def _along(plane: PlaneEstimate, heading: float, cfg) -> SlopeEstimate:
    """The plane along ``heading``, refused when the slope across it is too steep."""
    est = plane.along(heading)
    why = cross_refusal(est, cfg["slope.max_cross_deg"])
    if why is not None:
        est.refusal = why
    return est


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


#: how a leg's refusal on a rangefinder dropout begins
DROPOUT = "rangefinder dropout"


def _loiter(link: Link, spot, heading: float | None) -> None:
    """Hold the spot (a position target), then ask the autopilot for LOITER: the pass is over and
    nobody sends GUIDED targets any more; the pilot takes it from there."""
    _send(link, *spot, heading)
    link.command(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, LOITER, retries=3)


def _at_rest_over(link: Link, spot, heading: float) -> bool:
    """At rest over the spot: within AT_SPOT_M of it along ``heading``, ACROSS_SPOT_M across."""
    p = link.last.get("LOCAL_POSITION_NED")
    if p is None:
        return False
    along, across = _offsets(p, spot, heading)
    return (
        abs(along) < AT_SPOT_M
        and abs(across) < ACROSS_SPOT_M
        and abs(p.vx) < AT_REST_MPS
        and abs(p.vy) < AT_REST_MPS
        and abs(p.vz) < AT_REST_MPS
    )


def _offsets(p, spot, heading: float) -> tuple[float, float]:
    """The position ``p``'s offset from the spot along ``heading`` and across it (to its right)."""
    a = math.radians(heading)
    dn, de = p.x - spot[0], p.y - spot[1]
    return dn * math.cos(a) + de * math.sin(a), -dn * math.sin(a) + de * math.cos(a)


def _where(link: Link, spot, heading: float) -> str:
    """Where the vehicle is from the spot, for a refusal."""
    p = link.last.get("LOCAL_POSITION_NED")
    if p is None:
        return "no position"
    along, across = _offsets(p, spot, heading)
    speed = math.sqrt(p.vx**2 + p.vy**2 + p.vz**2)
    return f"{along:+.2f} m along, {across:+.2f} m across the spot at {speed:.2f} m/s"


def _turn(
    link: Link,
    cfg,
    track: SurfaceTrack,
    spot,
    heading: float,
    plane: PlaneEstimate | None,
    tick,
    wall_s: float,
    note: Callable[[str], None],
) -> str | None:
    """Hold the spot and turn to ``heading``; None once there and at rest, else why not. With a
    ``plane``, "there" is: the slope across the vehicle's heading within half of
    ``slope.max_cross_deg`` (on a steep roof a degree of heading is most of a degree across);
    without, within :data:`LEG_HEADING_DEG`."""
    limit = cfg["slope.turn_timeout_s"]
    half_cross = 0.5 * cfg["slope.max_cross_deg"]
    t0 = link.clock.now()
    end_wall = time.monotonic() + wall_s
    last_sent = -1.0
    told = False
    while True:
        tick()
        why = survey_refusal(link)
        if why is not None:
            return why
        now = link.clock.now()
        if now - last_sent >= 1.0 / SEND_HZ or now < last_sent:
            _send(link, *spot, heading)
            last_sent = now
        have = track.heading_deg()
        off = abs(wrap_deg(heading - have)) if have is not None else 180.0
        if plane is not None and have is not None:
            there = abs(plane.slope_along(have + 90.0)[0]) <= half_cross
        else:
            there = off <= LEG_HEADING_DEG
        if not told and off > LEG_HEADING_DEG:
            note(f"survey: turning from {az_text(have or 0.0)} to face {az_text(heading)}")
            told = True
        if there and _at_rest_over(link, spot, heading):
            return None
        if now - t0 > limit or time.monotonic() > end_wall:
            at = "no heading" if have is None else f"heading {have:.1f} deg"
            return (
                f"not facing {az_text(heading)} at rest over the spot within {limit:g} s "
                f"({at}, {_where(link, spot, heading)})"
            )
        time.sleep(0.001)


def _fly_leg(
    link: Link,
    cfg,
    track: SurfaceTrack,
    spot,
    heading: float,
    tick,
    wall_s: float,
    note: Callable[[str], None] = print,
) -> str | None:
    """Fly one leg along ``heading``, facing it; None when the vehicle is back at rest over the
    spot, else why not.

    The target moves at the survey speed toward each end in turn (behind the spot, then ahead),
    then back to the spot. The leg holds its height while the surface may rise under it: where
    the range reads below ``slope.survey_min_range_m`` (or will, by the time a vehicle turned now
    has stopped) the target turns back at once (uphill on a steep roof: at 60 deg, 1 m of the pass
    rises the roof 1.7 m, into a vehicle hovering 1 m over the spot). With no in-range reading for
    :data:`RANGE_LOST_S` while it flies out, that guard is blind: the target stops where the
    vehicle is and comes back to the spot (over ground this leg has flown at this height), and the
    leg ends refused (:data:`DROPOUT`)."""
    n0, e0, d0 = spot
    u = (math.cos(math.radians(heading)), math.sin(math.radians(heading)))
    half = cfg["slope.survey_length_m"] / 2
    v = cfg["slope.survey_speed_mps"]
    min_range = cfg["slope.survey_min_range_m"]
    goals = [-half, half, 0.0]  # along the heading from the spot
    leg = 0
    target = 0.0
    t0 = link.clock.now()
    last_t = t0
    limit = cfg["slope.survey_timeout_s"]
    end_wall = time.monotonic() + wall_s
    last_sent = -1.0
    dropout: str | None = None
    while True:
        tick()
        why = survey_refusal(link)
        if why is not None:
            return why
        now = link.clock.now()
        el = now - t0
        if el > limit or time.monotonic() > end_wall:
            _send(link, n0, e0, d0, heading)
            return f"not back over the spot within {limit:g} s ({_where(link, spot, heading)})"
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
        along = (here.x - n0) * u[0] + (here.y - e0) * u[1] if here is not None else target
        # guarded: going out behind, and ahead of the spot going out ahead (between the far end
        # behind and the spot the vehicle has just flown; a turn there would undo the pass)
        guarded = leg == 0 or (leg == 1 and along >= 0.0)
        newest = track.ranges[-1][0] if track.ranges else -math.inf
        blind = now - max(newest, t0)
        if dropout is None and leg < len(goals) - 1 and blind > RANGE_LOST_S:
            # the guard below has nothing to guard with: stop, and back to the spot
            dropout = (
                f"{DROPOUT}: no in-range reading for {blind:.2f} s at {along:+.2f} m toward "
                f"{az_text(heading)} of the spot"
            )
            note(f"survey: {dropout}: pass aborted, back over the spot")
            target, leg, last_sent = along, len(goals) - 1, -1.0
        r = low_range(track, now, min_range) if guarded and dropout is None else None
        if r is not None:  # the surface rises ahead
            target = along  # the target leads the vehicle: turn where the vehicle is
            note(
                f"survey: range falling to {r:.2f} m {target:+.2f} m toward {az_text(heading)} "
                "of the spot: turned back"
            )
            leg += 1
            last_sent = -1.0  # the new direction goes out now
        if now - last_sent >= 1.0 / SEND_HZ or now < last_sent:
            _send(link, n0 + target * u[0], e0 + target * u[1], d0, heading)
            last_sent = now
        if leg >= len(goals) and _at_rest_over(link, spot, heading):
            return dropout
        time.sleep(0.001)


def _send(link: Link, n: float, e: float, d: float, heading_deg: float | None = None) -> None:
    """A GUIDED position target (LOCAL_NED) and, given one, the heading to face (deg)."""
    info = link.info
    if info is None:
        return
    yaw = 0.0 if heading_deg is None else math.radians(wrap_deg(heading_deg))
    link.conn.mav.set_position_target_local_ned_send(
        int(link.clock.now() * 1000) & 0xFFFFFFFF,
        info.system,
        info.component,
        mavlink.MAV_FRAME_LOCAL_NED,
        POSITION_MASK if heading_deg is None else POSITION_YAW_MASK,
        float(n),
        float(e),
        float(d),
        0,
        0,
        0,
        0,
        0,
        0,
        yaw,
        0,
    )
