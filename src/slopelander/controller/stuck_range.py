"""A rangefinder that stops changing while the vehicle descends: told from the descent it reports.

The on-board script cuts on the range alone, so a range stuck above the cut height lets the vehicle
meet the roof under power (found by a 200-landing soak on ArduCopter SITL: the reading held one
value for 1.7-3 s in ARMED, contact at 0.46 m/s with the motors running). Nothing else notices it:
the reading stays fresh, in range and flagged valid. Here the readings of the last
``range.stuck_window_s`` (by their own time) are compared with the descent LOCAL_POSITION_NED
reports over the same span: a range whose readings all lie within ``range.stuck_fraction`` of that
descent is stuck. The descent counted is the approach to the roof: the vehicle's fall less the
roof's fall under it as it moves (LOCAL_POSITION_NED and the roof plane the landing knows,
:func:`~slopelander.controller.roof.rise_over_roof`). A descent drifting downhill sees the range
fall slower than it descends, by the drift times the slope's tangent: the outdoor campaign on
ArduCopter (drifts of up to 0.4 m/s over 25-45 deg roofs) aborted 5 of 15 landings "range stuck"
on a range that moved 0.04-0.08 m in 0.6 s, as the roof's fall said it would, while the vehicle
descended 0.15-0.31 m. And each reading is taken as the height over the roof it means along the
beam at that moment (:func:`~slopelander.controller.roof.height_from_beam`, the ATTITUDE nearest
the reading): over a 43 deg roof the body pitching 5 deg nose-up lengthened the beam by 0.14 m
while the vehicle came 0.19 m nearer, in the same campaign. The spread (highest less lowest),
not the decrease, is compared: over a roof edge the reading moves either way, and a moving
reading is not a stuck one. Judged only
while the vehicle reports descending, and approaching the roof, at least half the commanded rate
(``descent.rate_mps``): hovering (ARMED waiting for the script), or drifting downhill as fast as
it descends, the range has no reason to move.
Nor when every reading of the window lies at or below the cut height (``reflex.cut_height_m``):
the script cuts on such a reading once it has lasted (its RESEED_MS, 0.6 s: a low reading that
lasts is a real change of the ground, or a false cut the script's missed-impact rule then
handles), and an abort racing that cut would ask LOITER of a vehicle whose motors are stopping
(found on ArduCopter: a reading held at 0.15 m, 1.3 m over the roof, aborted 0.05 s before the
script's cut).
"""

from __future__ import annotations

import itertools
from collections import deque
from typing import Any

from slopelander.controller.roof import height_from_beam, rise_over_roof, roof_plane

#: judged only while the reported descent averages at least this share of the commanded rate
MIN_DESCENT_SHARE = 0.5


class StuckRange:
    """Fed each step of the descent; :meth:`feed` returns why the range is stuck, or None."""

    def __init__(self, cfg: Any) -> None:
        self.window_s = float(cfg["range.stuck_window_s"])
        self.fraction = float(cfg["range.stuck_fraction"])
        self.min_samples = int(cfg["range.stuck_min_samples"])
        self.min_descent_mps = MIN_DESCENT_SHARE * float(cfg["descent.rate_mps"])
        self.cut_m = float(cfg["reflex.cut_height_m"])
        #: (reading's time, range m, reported descent m/s, position NED m or None, height over the
        #: roof the reading means m) per reading
        self.samples: deque[tuple[float, float, float, Any, float]] = deque()

    def feed(
        self,
        range_t: float | None,
        range_m: float | None,
        descent_mps: float | None,
        position_m: tuple[float, float, float] | None = None,
        roof: tuple[float | None, float | None, float | None] = (None, None, None),
        beam: tuple[float, float, float] | None = None,
    ) -> str | None:
        """One step: the reading's own time, the reading (None: not valid), the descent (m/s,
        down) and the position (m, north-east-down) the vehicle reports (None: unknown), the roof
        (:func:`~slopelander.controller.roof.roof_plane`) and the beam at the reading (None: the
        reading is taken as it is). A missing reading or descent starts over. Without a position
        or the roof's slope and heading, the approach is the descent alone."""
        if not self._add(range_t, range_m, descent_mps, position_m, roof, beam):
            return None
        s = self.samples
        span = s[-1][0] - s[0][0]
        if span < self.window_s or len(s) < self.min_samples:
            return None
        expected = self._approach(roof, span)
        if expected is None or max(x[1] for x in s) <= self.cut_m:
            return None  # not approaching; or at the cut height: the script's to cut on
        moved = max(x[4] for x in s) - min(x[4] for x in s)
        if moved < self.fraction * expected:
            return (
                f"range stuck: {moved:.2f} m of change over {span:.2f} s "
                f"while the vehicle came {expected:.2f} m nearer the roof"
            )
        return None

    def _add(self, range_t, range_m, descent_mps, position_m, roof, beam) -> bool:
        """Keep a new distinct reading (and forget those before the window); False when there is
        none (a missing reading or descent also starts over)."""
        s = self.samples
        if range_t is None or range_m is None or descent_mps is None:
            s.clear()
            return False
        if s and range_t <= s[-1][0]:
            return False  # the same reading again (or an older one): no new sample
        height = range_m if beam is None else height_from_beam(range_m, beam, *roof)
        s.append((range_t, range_m, descent_mps, position_m, height))
        while len(s) >= 2 and s[1][0] <= range_t - self.window_s:
            s.popleft()  # the oldest kept is the last one at or before the window's start
        return True

    def _approach(self, roof, span: float) -> float | None:
        """How much nearer the roof the vehicle came over the window (m), or None when it did not
        descend, or approach, at least the judged share of the commanded rate: the descent
        reported step by step (the earlier sample's speed), less the roof's fall under it when
        its position and the roof's slope and heading are known."""
        s = self.samples
        descent = sum(a[2] * (b[0] - a[0]) for a, b in itertools.pairwise(s))
        least = self.min_descent_mps * span
        if descent < least:
            return None
        first, last = s[0][3], s[-1][3]
        if first is None or last is None or roof[0] is None or roof[1] is None:
            return descent
        approach = -rise_over_roof(first, last, *roof)
        return approach if approach >= least else None  # drifting downhill as fast: no reason


def range_stuck(ctx: Any, inp: Any) -> str | None:
    """The descent states' check (DESCEND, ARMED): one watcher per descent, kept in
    ``ctx.marks["stuck_range"]`` (DESCEND starts it anew)."""
    watch = ctx.marks.get("stuck_range")
    if watch is None:
        watch = ctx.marks["stuck_range"] = StuckRange(ctx.cfg)
    descent = -inp.climb_mps if inp.climb_mps is not None else None
    stamp = inp.range_t if inp.range_t is not None else inp.t
    roof = roof_plane(inp.slope_measured, ctx.slope_deg, inp.heading_deg)
    reading = inp.range_m if inp.range_valid else None
    return watch.feed(stamp, reading, descent, inp.position_m, roof, inp.beam_ned)
