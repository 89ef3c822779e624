"""A rangefinder that stops changing while the vehicle descends: told from the descent it reports.

The on-board script cuts on the range alone, so a range stuck above the cut height lets the vehicle
meet the roof under power (found by a 200-landing soak on ArduCopter SITL: the reading held one
value for 1.7-3 s in ARMED, contact at 0.46 m/s with the motors running). Nothing else notices it:
the reading stays fresh, in range and flagged valid. Here the readings of the last
``range.stuck_window_s`` (by their own time) are compared with the descent LOCAL_POSITION_NED
reports over the same span: a range whose readings all lie within ``range.stuck_fraction`` of that
descent is stuck. The spread (highest less lowest), not the decrease, is compared: over a roof edge
or with the vehicle drifting along the slope the reading moves either way, and a moving reading is
not a stuck one. Judged only while the vehicle reports descending at least half the commanded rate
(``descent.rate_mps``): hovering (ARMED waiting for the script) the range has no reason to move.
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
        #: (reading's time, range m, reported descent m/s) per distinct reading
        self.samples: deque[tuple[float, float, float]] = deque()

    def feed(self, range_t: float | None, range_m: float | None, descent_mps: float | None) -> str | None:
        """One step: the reading's own time, the reading (None: not valid) and the descent (m/s,
        down) the vehicle reports (None: unknown). A missing reading or descent starts over."""
        if range_t is None or range_m is None or descent_mps is None:
            self.samples.clear()
            return None
        s = self.samples
        if s and range_t <= s[-1][0]:
            return None  # the same reading again (or an older one): no new sample
        s.append((range_t, range_m, descent_mps))
        while len(s) >= 2 and s[1][0] <= range_t - self.window_s:
            s.popleft()  # the oldest kept is the last one at or before the window's start
        span = range_t - s[0][0]
        if span < self.window_s or len(s) < self.min_samples:
            return None
        # the descent over the span, step by step (the earlier sample's reported speed)
        expected = sum(a[2] * (b[0] - a[0]) for a, b in itertools.pairwise(s))
        if expected < self.min_descent_mps * span:
            return None
        highest = max(r for _, r, _ in s)
        if highest <= self.cut_m:
            return None  # at the cut height: the script's to cut on, not stuck above it
        moved = highest - min(r for _, r, _ in s)
        if moved < self.fraction * expected:
            return (
                f"range stuck: {moved:.2f} m of change over {span:.2f} s "
                f"while the vehicle descended {expected:.2f} m"
            )
        return None


def range_stuck(ctx: Any, inp: Any) -> str | None:
    """The descent states' check (DESCEND, ARMED): one watcher per descent, kept in
    ``ctx.marks["stuck_range"]`` (DESCEND starts it anew)."""
    watch = ctx.marks.get("stuck_range")
    if watch is None:
        watch = ctx.marks["stuck_range"] = StuckRange(ctx.cfg)
    descent = -inp.climb_mps if inp.climb_mps is not None else None
    stamp = inp.range_t if inp.range_t is not None else inp.t
    return watch.feed(stamp, inp.range_m if inp.range_valid else None, descent)
