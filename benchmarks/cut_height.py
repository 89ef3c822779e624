"""The on-board cut's figures for one landing, from what a flight rig recorded
(``slopelander_sitl.rig.Track``),
and a side-by-side summary of landings saved by the landing benchmarks.

    python3 benchmarks/cut_height.py FILE.jsonl [FILE.jsonl ...]

``FILE.jsonl``: what ``benchmarks/landing_latency.py --save`` or ``benchmarks/outdoor_campaign.py
--save-conditions`` wrote, one landing a line, with its ``autopilot``. Prints, per autopilot, the
median and p99 of: the range at the moment the motors stopped minus the configured cut height
(the cut height error), contact minus that moment, contact -> reverse-thrust outputs; and the
p1, the cut height error's bad tail.

Where the figures come from (vehicle time, both autopilots alike):
- motors stopped: the physics' EV_STOP (the first frame whose four outputs are all in the ESCs'
  stop band); contact: EV_CONTACT; reverse thrust: EV_RVT (src/slopelander_sitl/vehicle/events.py);
- the range at EV_STOP: the rangefinder's own readings (DISTANCE_SENSOR, cm) in the
  ``FIT_S`` before EV_STOP, each distinct reading at the first message that carried it, fitted
  with a line (the steady descent) and read at EV_STOP. Both autopilots sample the rangefinder at
  20 Hz and send the newest sample in each DISTANCE_SENSOR, so a reading is stamped up to one
  stream period late: at a descent of 0.5 m/s and a 100 Hz stream the fitted range reads up to
  0.5 cm high. No physics truth is used: it is what a flight log gives on a real vehicle too.
- the last reading before EV_STOP: what the script had acted on (2 distinct samples at or below
  the cut; slopelander.lua).
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np

FIT_S = 0.5


def cut_figures(track, t0: float, cut_m: float) -> dict:
    """The cut's figures (s, m) for the landing that began at vehicle time ``t0`` with the cut at
    ``cut_m``: keys ``stop``, ``contact``, ``rvt`` (times), ``range_at_stop``, ``last_reading``,
    ``cut_error`` (range at stop - cut), ``contact_after_stop``, ``impact_to_rvt``; a key is
    absent when the flight did not show it (no stop, no contact, too few readings). With them,
    the evidence: ``script_states`` (the script's SL_STATE changes) and ``readings`` (the last 80
    distinct range readings)."""
    out: dict = {}
    # the evidence behind the figures, kept with them: the script's states (SL_STATE changes) and
    # the distinct range readings from the landing's start
    out["script_states"] = [(round(t, 3), code) for t, code in track.script if t >= t0]
    seen: list[tuple[float, float]] = []
    for t, r in track.ranges:
        if t >= t0 and (not seen or r != seen[-1][1]):
            seen.append((round(t, 3), r))
    out["readings"] = seen[-80:]
    stop = track.event_times("EV_STOP", t0)
    contact = track.contact(t0)
    if contact is not None:
        out["contact"] = contact["t"]
        rvt = track.event_times("EV_RVT", contact["t"] - 0.001)
        if rvt:
            out["rvt"] = rvt[0]
            out["impact_to_rvt"] = rvt[0] - contact["t"]
    if not stop:
        return out
    ts = stop[0]
    out["stop"] = ts
    if contact is not None:
        out["contact_after_stop"] = contact["t"] - ts
    firsts: list[tuple[float, float]] = []
    for t, r in track.ranges:
        if t < t0 or t > ts:
            continue
        if not firsts or r != firsts[-1][1]:
            firsts.append((t, r))
    if firsts:
        out["last_reading"] = firsts[-1][1]
    fit = [(t, r) for t, r in firsts if t >= ts - FIT_S]
    if len(fit) >= 3:
        tt = np.array([t for t, _ in fit]) - ts
        rr = np.array([r for _, r in fit])
        slope, at_stop = np.polyfit(tt, rr, 1)
        out["range_at_stop"] = float(at_stop)
        out["cut_error"] = float(at_stop) - cut_m
        out["descent_mps"] = float(-slope)
    return out


def stats_line(name: str, xs: list[float], unit: str = "ms", scale: float = 1000.0) -> str:
    """``name: median .., p1 .., p99 .. (min, max, n)`` of ``xs`` (scaled to ``unit``): both
    tails, as a cut height error's bad tail is the low one and a latency's the high one."""
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    if not xs:
        return f"{name}: no samples"
    a = np.array(xs) * scale
    return (
        f"{name}: median {np.median(a):.1f} {unit}, p1 {np.percentile(a, 1):.1f} {unit}, "
        f"p99 {np.percentile(a, 99):.1f} {unit} (min {a.min():.1f}, max {a.max():.1f}, n={len(a)})"
    )


def summary(rows: list[dict], autopilot: str) -> list[str]:
    """The figures of the landings in ``rows`` flown on ``autopilot``, one line each."""
    mine = [r for r in rows if r.get("autopilot", "sim") == autopilot]
    return [
        f"{autopilot}: {len(mine)} landings",
        "  "
        + stats_line(
            "cut height error (range at EV_STOP - cut)", [r.get("cut_error") for r in mine], "cm", 100.0
        ),
        "  "
        + stats_line(
            "last reading before EV_STOP - cut",
            [r["last_reading"] - r["cut"] for r in mine if "last_reading" in r],
            "cm",
            100.0,
        ),
        "  " + stats_line("EV_STOP -> EV_CONTACT", [r.get("contact_after_stop") for r in mine]),
        "  " + stats_line("EV_CONTACT -> EV_RVT", [r.get("impact_to_rvt") for r in mine]),
    ]


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    rows: list[dict] = []
    for name in argv:
        try:
            with open(name) as fh:
                rows += [json.loads(ln) for ln in fh if ln.strip()]
        except (OSError, json.JSONDecodeError) as exc:
            print(f"cut_height: {name}: {exc}", file=sys.stderr)
            return 2
    for ap in sorted({r.get("autopilot", "sim") for r in rows}):
        print("\n".join(summary(rows, ap)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
