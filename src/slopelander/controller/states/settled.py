"""SETTLED: the stock land detector is slow and may never fire on a slope, so the companion has the
vehicle disarmed, but only at rest (one sliding at a steady speed reads 1 g like one standing
still), and the landing ends only when the autopilot's HEARTBEAT says disarmed: a disarm sent is
not a disarm made (ArduCopter refuses a ground station's before its land detector fires)."""

from __future__ import annotations

import math
from typing import Any

from slopelander.controller.script_contract import state_name
from slopelander.controller.script_rules import GONE, LET_GO, reading
from slopelander.controller.states.base import Context, Inputs, State, keep_reflex, still
from slopelander.controller.states.reverse import SCRIPT_RVT

#: the window (vehicle s) over which a slide is measured as displacement per time
SLIDE_WINDOW_S = 0.5


def _drift(ctx: Context, inp: Inputs) -> float | None:
    """Speed over the ground (m/s) as the displacement over the last :data:`SLIDE_WINDOW_S` of
    vehicle time; None until positions cover most of the window, or while the position is
    unknown. One velocity sample is not a slide: after a link stall the impact's pivot read as a
    1.4 m/s slide 0.14 s after the cut."""
    track = ctx.marks.setdefault("settle_track", [])
    if inp.position_m is None:
        return None
    track.append((inp.t, inp.position_m))
    while len(track) > 2 and track[1][0] <= inp.t - SLIDE_WINDOW_S:
        track.pop(0)
    (t0, p0), (t1, p1) = track[0], track[-1]
    if t1 - t0 < 0.8 * SLIDE_WINDOW_S:
        return None
    return math.dist(p0, p1) / (t1 - t0)


def _moved(ctx: Context, inp: Inputs) -> float | None:
    """Distance (m) from where the vehicle was when SETTLED began (None: position unknown)."""
    if inp.position_m is None:
        return None
    start = ctx.marks.setdefault("settle_pos", inp.position_m)
    return math.dist(start, inp.position_m)


#: after the script disarmed as asked, how long (vehicle s) its IDLE may come before the HEARTBEAT
#: that says disarmed (ArduCopter's HEARTBEAT is 1 Hz unless asked faster)
DISARM_SEEN_S = 2.0
#: a script that let go unasked: this long (vehicle s) for a reordered or late announcement
LET_GO_S = 0.3

#: how often (vehicle s) an unanswered or refused disarm request is sent again
DISARM_RETRY_S = 0.5


def request_disarm(ctx: Context, inp: Inputs) -> None:
    """Ask the on-board script to disarm (it does while it holds the motors stopped and the
    vehicle is still: docs/onboard-script.md), at most every :data:`DISARM_RETRY_S`."""
    if inp.t - ctx.marks.get("disarm_sent", -1e9) >= DISARM_RETRY_S:
        ctx.act.disarm()
        ctx.marks["disarm_sent"] = inp.t


def request_ground_disarm(ctx: Context, inp: Inputs, forced: bool = False) -> None:
    """The companion's own disarm, at most every :data:`DISARM_RETRY_S`. Unforced, ArduCopter
    refuses it while its land detector says flying (AP_Arming_Copter::disarm: a GCS disarm needs
    ``ap.land_complete``), so it disarms a vehicle on the ground and never one in the air; on a
    steep roof that detector may never fire. ``forced`` (param 2 = 21196) skips the check: only
    for a vehicle the script would itself have disarmed (:meth:`Settled.without_script`)."""
    key = "forced_disarm_sent" if forced else "ground_disarm_sent"
    if inp.t - ctx.marks.get(key, -1e9) >= DISARM_RETRY_S:
        if forced:
            ctx.act.disarm_forced()
        else:
            ctx.act.disarm_on_ground()
        ctx.marks[key] = inp.t


#: a range this far above the cut height (m) says the vehicle is in the air, not on the roof: the
#: script's own margin for "left the roof" (LEAVE.MARGIN_M: the beam tilted by a touchdown's pivot)
AIR_MARGIN_M = 0.3
#: the script's LEAVE.TILT_DEG: tilted further from level, the beam (along the body's down axis)
#: meets the roof at a grazing angle or misses it, so its range says nothing of the ground below,
#: and the autopilot could not fly such a vehicle, only spin its motors up on the roof
BEAM_TILT_DEG = 60.0


def beam_height(inp: Inputs) -> float | None:
    """The height (m) the range gives as the script judges "left the roof": the beam's vertical
    share, ``range * cos(tilt)`` (the range alone when the tilt is unknown); None when the range
    is not valid or the body is tilted past :data:`BEAM_TILT_DEG`. Found on ArduCopter: a dead
    script's vehicle slid and pitched 47 deg up on a 20 deg roof, its beam reading 0.66 m along
    the roof (0.45 m vertically), and the range alone called it in the air: LOITER on the roof."""
    if not inp.range_valid:
        return None
    if inp.tilt_deg is None:
        return inp.range_m
    if not inp.tilt_deg <= BEAM_TILT_DEG:  # also NaN
        return None
    return inp.range_m * math.cos(math.radians(inp.tilt_deg))


def reads_in_the_air(cfg: Any, inp: Inputs) -> bool:
    """The range says the vehicle is in the air: its :func:`beam_height` over the cut height plus
    :data:`AIR_MARGIN_M` (the script's "left the roof" less its falling test: here the mixer may
    be flying the vehicle, which then reads 1 g like one on the roof), with the body within
    :data:`RESTING_TILT_DEG` of level: no vehicle hovers tilted further, and one lying so on a
    roof reads along it (found on ArduCopter: a dead script's vehicle at 60 deg on a 35 deg roof,
    its beam 1.26 m, 0.63 m vertically, was handed to LOITER)."""
    if inp.tilt_deg is not None and inp.tilt_deg > RESTING_TILT_DEG:
        return False
    h = beam_height(inp)
    return h is not None and h > cfg["reflex.cut_height_m"] + AIR_MARGIN_M


def reads_near_the_roof(cfg: Any, inp: Inputs) -> str | None:
    """Before the descent (PRESET, LEGS_WAIT, CHECKS) the vehicle hovers at its approach height;
    its :func:`beam_height` within the cut height plus :data:`AIR_MARGIN_M` of the roof says it is
    not there: why, or None. Found by the soak on ArduCopter: a vehicle whose altitude estimate
    ran 0.8 m high hovered 0.5 m over the roof while the legs were set, sank, and met the roof
    under power in LEGS_WAIT, its range reading 0.45 -> 0.34 m all the while."""
    h = beam_height(inp)
    limit = cfg["reflex.cut_height_m"] + AIR_MARGIN_M
    if h is None or h > limit:
        return None
    return (
        f"too near the roof before the descent: range {inp.range_m:.2f} m "
        f"({h:.2f} m vertically, under {limit:.2f} m)"
    )


#: a vehicle read still (speed and accelerometer, :func:`still`) tilted this far from level is
#: resting on something: hovering so, its thrust would push it sideways at g * tan(tilt) (5.7 m/s^2
#: at 30 deg) and it would not read still. Found on ArduCopter: a dead script's vehicle came to rest
#: pitched 47 deg on a 20 deg roof, its beam's vertical share 0.45 m, over the 0.36 m cut height,
#: and was never disarmed while the mixer drove its motors on the roof.
RESTING_TILT_DEG = 30.0


def reads_down(cfg: Any, inp: Inputs) -> bool:
    """The vehicle, once read still, is down: the range's :func:`beam_height` at or below the cut
    height (where the reflex itself would have cut), or the body tilted past
    :data:`RESTING_TILT_DEG` (no still vehicle hovers so)."""
    if inp.tilt_deg is not None and inp.tilt_deg > RESTING_TILT_DEG:
        return True
    h = beam_height(inp)
    return h is not None and h <= cfg["reflex.cut_height_m"]


class Settled(State):
    """On the roof with the motors held stopped by the script. Has the vehicle disarmed once it
    has been still (:func:`still`: accel 1 g and speed low) for ``settle.still_s``, and moves to
    LANDED when the HEARTBEAT shows it disarmed. A slide (displacement faster than
    ``settle.slide_speed_mps`` over :data:`SLIDE_WINDOW_S` and more than ``settle.slide_m`` from
    where SETTLED began) is not disarmed, and not handed to the autopilot either: spinning the
    rotors up on a tilted, sliding vehicle is no rescue. The motors stay held; the pilot may stop
    them (emergency stop) or command a take-off, which the script allows only level enough; a
    slide off the roof's edge is the script's to end (it gives the motors back when the range
    says the roof is gone). Not still by ``settle.timeout_s``: disarmed only if it is not moving
    (by displacement), else held and said so."""

    name = "SETTLED"
    reflex_owns = True

    def enter(self, ctx: Context, inp: Inputs) -> str | None:
        for k in (
            "still_since",
            "settle_pos",
            "settle_track",
            "disarm_sent",
            "disarm_asked",
            "said",
            "script_let_go",
            "gone_still_since",
            "ground_disarm_sent",
            "forced_disarm_sent",
        ):
            ctx.marks.pop(k, None)
        _moved(ctx, inp)
        _drift(ctx, inp)
        return None

    def _say_once(self, ctx: Context, key: str, text: str) -> None:
        said = ctx.marks.setdefault("said", set())
        if key not in said:
            said.add(key)
            ctx.act.statustext(text)

    @staticmethod
    def _sliding(cfg, drift: float | None, moved: float | None) -> bool:
        """Sliding: faster than ``settle.slide_speed_mps`` and further than ``settle.slide_m``."""
        fast = drift is not None and drift > cfg["settle.slide_speed_mps"]
        return fast and moved is not None and moved > cfg["settle.slide_m"]

    def step(self, ctx: Context, inp: Inputs):
        cfg = ctx.cfg
        if not inp.armed:
            how = ctx.marks.get("disarm_asked", "by the autopilot")
            return ("LANDED", f"disarmed ({how}): seen in the HEARTBEAT")
        script = reading(inp.script_state, inp.script_present)
        if script in GONE:
            return self.without_script(ctx, inp, script)
        if script == "FAULT_HELD":
            # the script failed after the cut and holds the motors stopped until disarmed: it
            # refuses a take-off release and an abort, so the only end is the disarm, asked every
            # DISARM_RETRY_S (it disarms once the vehicle has been still for a second)
            ctx.marks.setdefault("disarm_asked", "script fault, motors held")
            self._say_once(ctx, "fault", "SL script fault: motors held, disarm once still")
            # a slide is said as any held slide is (the pilot's to judge; found by the soak on
            # ArduCopter: a 47 deg roof, 1.04 m/s for minutes, the script refusing the disarm
            # while moving and nobody told it slid)
            drift, moved = _drift(ctx, inp), _moved(ctx, inp)
            if self._sliding(cfg, drift, moved):
                self._say_once(
                    ctx, "slide", f"sliding at {drift:.2f} m/s, {moved:.2f} m: motors held (script fault)"
                )
            request_disarm(ctx, inp)
            return None
        if inp.takeoff_request:
            return ("TAKEOFF", "take-off commanded on the roof")
        if inp.script_state in LET_GO:
            # the script let go while armed: it gave the motors back (the range says the vehicle
            # left the roof, or its validity lapsed) and the autopilot flies. But a script that
            # disarmed as asked says IDLE before the next HEARTBEAT says disarmed: wait for that.
            since = ctx.marks.setdefault("script_let_go", inp.t)
            grace = DISARM_SEEN_S if "disarm_asked" in ctx.marks else LET_GO_S
            if inp.t - since > grace:
                now = state_name(inp.script_state)
                return ("ABORTED", f"the on-board script gave the motors back ({now})")
            return None
        ctx.marks.pop("script_let_go", None)
        keep_reflex(ctx, inp, thrust_ended=True)  # SETTLED comes after the thrust
        drift, moved = _drift(ctx, inp), _moved(ctx, inp)
        if "disarm_asked" in ctx.marks:  # asked: the motors stay held until the HEARTBEAT says so
            request_disarm(ctx, inp)
            return None
        if self._sliding(cfg, drift, moved):
            ctx.marks.pop("still_since", None)
            self._say_once(
                ctx, "slide", f"sliding at {drift:.2f} m/s, {moved:.2f} m: motors held, not disarmed"
            )
            return None
        if still(cfg, inp):
            since = ctx.marks.setdefault("still_since", inp.t)
            # not while the script still ramps the reverse thrust down: the legs are unbending
            if inp.t - since >= cfg["settle.still_s"] and inp.script_state != SCRIPT_RVT:
                ctx.marks["disarm_asked"] = "still, motors held stopped"
                request_disarm(ctx, inp)
        else:
            ctx.marks.pop("still_since", None)
        if inp.t - ctx.entered_at >= cfg["settle.timeout_s"]:
            if drift is not None and drift <= cfg["settle.still_speed_mps"]:
                # not moving but the accelerometer keeps shaking (a vibrating sensor): the motors
                # are stopped either way, and it must not stay armed for ever
                ctx.marks["disarm_asked"] = "not still within the settle timeout but not moving"
                request_disarm(ctx, inp)
            else:
                what = "position unknown" if drift is None else f"moving at {drift:.2f} m/s"
                self._say_once(ctx, "timeout", f"{what} at the settle timeout: motors held, not disarmed")
        return None

    def without_script(self, ctx: Context, inp: Inputs, script: str):
        """After the cut with no script holding the motors (silent: dead, its overrides lapsed
        within 250 ms; FAULT: failed, or its faulted hold released by the emergency stop): the
        autopilot's mixer has the motors. The range decides, as the script reads it (the beam's
        vertical share, :func:`beam_height`). Above the cut height plus
        :data:`AIR_MARGIN_M` the vehicle is in the air (a false cut, or the mixer lifted it): the
        landing is aborted, the autopilot flies (climb setpoint, LOITER). Otherwise it is on the
        roof: the companion's unforced disarm every :data:`DISARM_RETRY_S`, and once the vehicle has
        read still for ``settle.still_s`` and down (:func:`reads_down`: at or below the cut height,
        where the reflex itself would have cut, or tilted past :data:`RESTING_TILT_DEG`) the
        forced one, as the script would have disarmed it."""
        cfg, what = ctx.cfg, script.lower()
        if reads_in_the_air(cfg, inp):
            tilt = "" if inp.tilt_deg is None else f", tilt {inp.tilt_deg:.0f} deg"
            high = f"range {inp.range_m:.2f} m{tilt}"
            return ("ABORTED", f"on-board script {what}, {high}: in the air, the autopilot flies")
        ctx.marks.setdefault("disarm_asked", f"on-board script {what}: the companion's own disarm")
        self._say_once(ctx, "gone", f"SL script {what} on the roof: disarming")
        request_ground_disarm(ctx, inp)
        if still(cfg, inp) and reads_down(cfg, inp):
            since = ctx.marks.setdefault("gone_still_since", inp.t)
            if inp.t - since >= cfg["settle.still_s"]:
                request_ground_disarm(ctx, inp, forced=True)
        else:
            ctx.marks.pop("gone_still_since", None)
        return None
