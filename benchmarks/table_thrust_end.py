"""The shipped lookup table's presets flown by the model with the reverse thrust held (as the table
was computed) and ended as the companion ends it: held for a fixed time, then stopped as a step
or ramped down. Prints, per band of slopes, how many cells land in each case and which change.

    python3 benchmarks/table_thrust_end.py [--duration 0.6] [--ramp 1.0] [--table FILE]

Every cell of the table is one landing at its own (slope, speed) with its own preset and the
table's reverse thrust (100 % at impact). The companion holds the thrust at least
``reflex.reverse_thrust_ms`` (0.5 s) and then until the vehicle has read still for
``reflex.reverse_still_s`` (0.2 s); flown, that came to 0.56-0.64 s after contact
(benchmarks/outdoor_campaign.py). The model takes a fixed duration instead (``--duration``,
assumed the same for every cell): a cell that bounces longer would be held longer in flight.
The "re-chosen" columns choose the presets again on the table's grid, with the thrust held (as
the table was made) and with the ended, ramped thrust (what ``slopelander table
--reverse-duration D --reverse-ramp R`` would write), and count the cells that land.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src")]

import numpy as np  # noqa: E402

from slopelander.controller.table import DEFAULT_TABLE, LookupTable  # noqa: E402
from slopelander.envelope import MapAxes, choose_presets  # noqa: E402
from slopelander.envelope.presets import STRATEGIES  # noqa: E402
from slopelander.model import Model, Outcome, default_conditions, simulate_batch  # noqa: E402

BANDS = [(0, 30), (30, 40), (40, 45), (45, 50), (50, 60.01)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=0.6, help="s the thrust is held (default 0.6)")
    ap.add_argument("--ramp", type=float, default=1.0, help="s of the ramp to zero (default 1.0)")
    ap.add_argument("--table", default=str(DEFAULT_TABLE))
    a = ap.parse_args()
    table = LookupTable.load(a.table)
    st = table.strategy
    n_s, n_v = len(table.slopes), len(table.speeds)
    grid = default_conditions(n_s * n_v)
    grid["slope_deg"] = np.repeat(table.slopes, n_v)
    grid["speed"] = np.tile(table.speeds, n_s)
    for name in ("tau_up", "tau_down", "angle_up_deg", "angle_down_deg"):
        grid[name] = table.cells[name].ravel()
    grid["reverse_percent"] = float(st.get("reverse_percent", 0.0))
    grid["reverse_delay"] = float(st.get("reverse_delay", 0.0))
    if not grid["reverse_percent"].any():
        raise SystemExit(f"{a.table}: the table's strategy has no reverse thrust to end")
    model = Model.default()
    cases = {"held": (np.inf, 0.0), "step": (a.duration, 0.0), f"ramp {a.ramp:g} s": (a.duration, a.ramp)}
    landed, codes = {}, {}
    t0 = time.perf_counter()
    for name, (dur, ramp) in cases.items():
        g = grid.copy()
        g["reverse_duration"], g["reverse_ramp"] = dur, ramp
        r = simulate_batch(g, model)
        codes[name] = r["outcome"].reshape(n_s, n_v)
        landed[name] = codes[name] <= Outcome.END_OF_TRAVEL
    table_landed = np.isin(table.cells["outcome"], ["ideal", "under_used", "end_of_travel"])
    same = int((landed["held"] == table_landed).sum())
    print(
        f"{a.table}: {n_s} slopes x {n_v} speeds; thrust held {a.duration:g} s after its command; "
        f"{time.perf_counter() - t0:.0f} s for {3 * n_s * n_v} landings"
    )
    print(f"held: the model lands the table's own 'landed' cells: {same}/{n_s * n_v} cells agree")

    # presets chosen again with the ramped end, on a coarse grid
    t1 = time.perf_counter()
    axes = MapAxes(np.asarray(table.slopes, float), np.asarray(table.speeds, float))
    rechosen, maps = {}, {}
    for name, (dur, ramp) in (("held", (None, 0.0)), ("ended", (a.duration, a.ramp))):
        strat = STRATEGIES[st.get("name", "rvt")].with_options(
            refine=st.get("torques") == "refined",
            optimal_angle=st.get("angle") == "optimal",
            reverse_duration=dur,
            reverse_ramp=ramp,
        )
        maps[name] = choose_presets(model, axes, strat, progress=False)
        rechosen[name] = (maps[name].outcome <= Outcome.END_OF_TRAVEL, axes.slopes)
    changed = np.zeros((n_s, n_v), bool)
    for f in ("tau_up", "tau_down", "angle_up_deg", "angle_down_deg"):
        changed |= ~np.isclose(maps["held"].fields[f], maps["ended"].fields[f])
    print(
        f"presets re-chosen on the table's {n_s} x {n_v} cells: {time.perf_counter() - t1:.0f} s; "
        f"the ended thrust chooses another preset in {int(changed.sum())} cells"
    )

    head = "  ".join(f"{n:>12}" for n in cases)
    print(
        f"\n{'slopes (deg)':>14}  {'cells':>5}  {head}  {'re-chosen held':>14} {'re-chosen ended':>15} "
        f"{'other preset':>12}"
    )
    for lo, hi in BANDS:
        rows = (table.slopes >= lo) & (table.slopes < hi)
        cols = "  ".join(f"{int(landed[n][rows].sum()):>12}" for n in cases)
        rc = []
        for name in ("held", "ended"):
            ok, sl = rechosen[name]
            sel = (sl >= lo) & (sl < hi)
            rc.append(f"{int(ok[sel].sum())}/{int(sel.sum()) * ok.shape[1]}")
        print(
            f"{lo:6.1f}-{hi:<6.1f}  {int(rows.sum()) * n_v:>5}  {cols}  {rc[0]:>14} {rc[1]:>15} "
            f"{int(changed[rows].sum()):>12}"
        )
    tot = "  ".join(f"{int(landed[n].sum()):>12}" for n in cases)
    rc = [f"{int(rechosen[n][0].sum())}/{rechosen[n][0].size}" for n in ("held", "ended")]
    print(f"{'all':>14}  {n_s * n_v:>5}  {tot}  {rc[0]:>14} {rc[1]:>15} {int(changed.sum()):>12}")

    ramp_name = list(cases)[2]
    lost = landed["held"] & ~landed[ramp_name]
    print(f"\ncells the table lands with the thrust held but not with it ended and ramped: {int(lost.sum())}")
    for i, j in zip(*np.nonzero(lost), strict=True):
        c = table.cell(i, j)
        print(
            f"  {table.slopes[i]:4.0f} deg {table.speeds[j]:4.1f} m/s  "
            f"preset {c.tau_up:.2f}/{c.tau_down:.2f} up {c.angle_up_deg:.1f} deg: "
            f"held {Outcome(codes['held'][i, j])}, step {Outcome(codes['step'][i, j])}, "
            f"ramp {Outcome(codes[ramp_name][i, j])}"
        )


if __name__ == "__main__":
    main()
