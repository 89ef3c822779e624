"""The stock rigid gear: its contact, its structural limit, and the area ratio of Fig. 11.

Prints, on the shipped model:

1. level drops of the rigid gear: how long the first contact lasts and the restitution (rebound
   speed / impact speed), against the paper's "rebounds of 10-30 ms" (Sec. I);
2. the peak foot load of a level landing at 2.75 / 2 m/s, which ``rigid_load_limit`` is;
3. the rigid gear's green (ideal) area on the default grid, its outcome counts, and the ratio
   FSA + RVT / rigid on green cells (the paper's 8x);
4. how that ratio moves with the contact's two assumptions (contact time, restitution), each
   with its own load limit re-derived the same way, and with the limit or the contact removed.

    python benchmarks/rigid_gear.py [--slope-step 1] [--speed-step 0.1] [--no-sensitivity]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src")]

import numpy as np  # noqa: E402

from slopelander.envelope.axes import MapAxes  # noqa: E402
from slopelander.envelope.maps import envelope_area, max_slope  # noqa: E402
from slopelander.envelope.presets import choose_presets  # noqa: E402
from slopelander.model import LandingConditions, Model, Outcome, simulate  # noqa: E402
from slopelander.model import kernel as k  # noqa: E402

LIMIT_SPEED = 2.75 / 2  # m/s: the paper's FSA lands at 2.75 m/s, "more than double" the stock gear


def contact_for(model: Model, contact_time: float, restitution: float) -> dict[str, float]:
    """Spring and damper giving a linear contact of this duration and restitution on half the
    vehicle's mass (one planar foot of a level landing)."""
    m = 0.5 * (model.params["body_mass"] + 2 * model.params["leg_mass"])
    ln_e = math.log(restitution)
    return {
        "rigid_contact_stiffness": m * (math.pi**2 + ln_e**2) / contact_time**2,
        "rigid_contact_damping": -2.0 * m * ln_e / contact_time,
    }


def level_drop(model: Model, speed: float) -> tuple[float, float, float]:
    """First contact's duration (s), restitution, and the landing's peak foot load (N)."""
    tr = simulate(LandingConditions(slope_deg=0.0, speed=speed), model.rigid(), sample_rate=1 / model.dt)
    on = tr.raw[:, k.S_NF : k.S_NF + 2].sum(axis=1) > 0.0
    i0 = int(np.argmax(on))
    i1 = i0 + int(np.argmax(~on[i0:]))
    return tr.t[i1] - tr.t[i0], tr.raw[i1, k.S_V + 1] / speed, tr.peak_foot_load


def derived_limit(model: Model) -> float:
    return level_drop(model, LIMIT_SPEED)[2]


def rigid_area(model: Model, axes: MapAxes) -> tuple[float, float, dict[str, int]]:
    m = choose_presets(model, axes, "rigid", progress=False)
    counts = {str(o): int((m.outcome == o).sum()) for o in Outcome}
    return envelope_area(m), max_slope(m), counts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slope-step", type=float, default=1.0)
    ap.add_argument("--speed-step", type=float, default=0.1)
    ap.add_argument("--no-sensitivity", action="store_true", help="skip part 4")
    a = ap.parse_args()
    model = Model.default()
    axes = MapAxes.build(a.slope_step, a.speed_step)
    t0 = time.perf_counter()

    print("## 1. Level drops of the rigid gear (shipped contact)")
    print("| impact speed m/s | first contact ms | restitution | peak foot load N |")
    print("|---|---|---|---|")
    for v in (0.5, 1.0, LIMIT_SPEED, 2.0, 3.0):
        dur, e, peak = level_drop(model, v)
        print(f"| {v:.3f} | {1000 * dur:.1f} | {e:.2f} | {peak:.1f} |")

    limit = derived_limit(model)
    print(f"\n## 2. Structural limit: peak foot load of a level landing at {LIMIT_SPEED} m/s = {limit:.1f} N")
    print(f"   shipped rigid_load_limit = {model.params['rigid_load_limit']:g} N")

    print(f"\n## 3. Envelopes on green cells, grid {axes.shape[0]} x {axes.shape[1]}")
    fsa = choose_presets(model, axes, "rvt", progress=False)
    fsa_area = envelope_area(fsa)
    area, smax, counts = rigid_area(model, axes)
    print(f"FSA + RVT: ideal area {fsa_area:.1f} deg*m/s, max ideal slope {max_slope(fsa):g} deg")
    print(f"rigid gear: ideal area {area:.1f} deg*m/s, max ideal slope {smax:g} deg; cells {counts}")
    rvt = choose_presets(model, axes, "rigid_rvt", progress=False)
    rvt_area, rvt_max = envelope_area(rvt), max_slope(rvt)
    print(f"rigid gear + RVT: ideal area {rvt_area:.1f} deg*m/s, max ideal slope {rvt_max:g} deg")
    print(f"ratio FSA + RVT / rigid (green cells): {fsa_area / area:.2f}x (paper: 8x)")

    if not a.no_sensitivity:
        print("\n## 4. Sensitivity: contact time and restitution (limit re-derived for each)")
        print("| contact time ms | restitution | limit N | rigid ideal area | max ideal slope | ratio |")
        print("|---|---|---|---|---|---|")
        for tc in (0.010, 0.020, 0.030):
            for e in (0.3, 0.5, 0.7):
                m = model.with_params("assumed", **contact_for(model, tc, e))
                m = m.with_params("derived", rigid_load_limit=derived_limit(m))
                ar, sm, _ = rigid_area(m, axes)
                ratio = fsa_area / ar if ar else math.inf
                lim = m.params["rigid_load_limit"]
                print(f"| {1000 * tc:.0f} | {e:.1f} | {lim:.0f} | {ar:.1f} | {sm:g} | {ratio:.2f}x |")
        print(
            "\n| limit from a level landing at m/s | limit N | rigid ideal area | max ideal slope | ratio |"
        )
        print("|---|---|---|---|---|")
        for v in (1.0, 1.2, LIMIT_SPEED):
            lim = level_drop(model, v)[2]
            ar, sm, _ = rigid_area(model.with_params("assumed", rigid_load_limit=lim), axes)
            print(f"| {v:.3f} | {lim:.0f} | {ar:.1f} | {sm:g} | {fsa_area / ar:.2f}x |")
        variants = {
            "shipped contact, no structural limit": model.with_params("assumed", rigid_load_limit=1e5),
            "FSA rubber-foot contact (k_g, b_g), no limit (the model before)": model.with_params(
                "assumed",
                rigid_contact_stiffness=model.params["ground_stiffness"],
                rigid_contact_damping=model.params["ground_damping"],
                rigid_load_limit=1e5,
            ),
        }
        for label, m in variants.items():
            ar, sm, counts = rigid_area(m, axes)
            print(f"{label}: rigid ideal area {ar:.1f}, max slope {sm:g} deg, ratio {fsa_area / ar:.2f}x")
            print(f"    cells {counts}")
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
