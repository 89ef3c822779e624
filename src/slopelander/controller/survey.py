"""Measuring the slope before PRESET: the estimate from what the rangefinder has seen near the
spot, and when that is too little, a short survey pass the companion flies itself.

The pass: in GUIDED, armed, at the hover's height (NED down held), a position target moving at
``slope.survey_speed_mps`` from the spot ``slope.survey_length_m``/2 south, then the whole length
north, then back to the spot, where the vehicle must come to rest before the landing starts. It
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
    done = _fly_pass(link, cfg, track, (spot_n, spot_e, spot_d), tick, wall_s)
    took = link.clock.now() - t0
    est = estimate(track.points(), spot_n, st)
    if done is not None:
        est.refusal = f"survey pass not finished: {done}"
    return est, took


def _fly_pass(link: Link, cfg, track: SurfaceTrack, spot, tick, wall_s: float) -> str | None:
    """Fly the pass; None when the vehicle is back at rest over the spot, else why not."""
    n0, e0, d0 = spot
    half = cfg["slope.survey_length_m"] / 2
    v = cfg["slope.survey_speed_mps"]
    legs = [(n0, n0 - half), (n0 - half, n0 + half), (n0 + half, n0)]
    durations = [abs(b - a) / v for a, b in legs]
    t0 = link.clock.now()
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
        target = n0
        rest = el
        for (a, b), dur in zip(legs, durations, strict=True):
            if rest <= dur:
                target = a + (b - a) * (rest / dur if dur > 0 else 1.0)
                break
            rest -= dur
        if now - last_sent >= 1.0 / SEND_HZ or now < last_sent:
            _send(link, target, e0, d0)
            last_sent = now
        if el > sum(durations):
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
