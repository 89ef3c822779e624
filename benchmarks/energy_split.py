"""Where a landing's energy goes, across the envelope, from the model's own bookkeeping.

For each slope and vertical impact speed, a drop with the legs at the same torque lands with rotors
off; when it comes to rest (or after the horizon) the energy it brought — kinetic energy at contact
plus the potential energy it lost while landing — has gone into joint friction, the flex dampers,
the end stops, the ground damper and the feet's friction. The table is printed for the model's
reading of a planar leg (``joints_per_planar_leg`` = 2: a pair of real legs) and, for comparison,
for one real leg per planar leg. The question it answers: do the friction joints take the share
of the energy the paper's text describes ("well-used legs"), or do the ground and feet take it?

    python benchmarks/energy_split.py [--tau 1.7] [--horizon 2.0]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src")]

from slopelander.model import Model  # noqa: E402
from slopelander.model.stepper import DISSIPATION_TERMS, Stepper  # noqa: E402

SHOWN = ("joint_friction", "flex_damper", "eot_damper", "ground_damper", "foot_friction")


def split(model: Model, slope: float, speed: float, tau: float, horizon: float) -> dict[str, float]:
    s = Stepper(model, slope_deg=slope)
    s.set_friction(tau, tau)
    s.place(height=0.001, vz=-speed)
    e0 = sum(s.energy().values())
    t = 0.0
    while t < horizon:
        s.step(0.002, 0.0, 0.0)
        t += 0.002
    d = s.dissipated()
    total = sum(d[n] for n in DISSIPATION_TERMS if n != "rotor_work")
    out = {n: d.get(n, 0.0) / total if total > 0 else 0.0 for n in SHOWN}
    out["total_J"] = total
    out["brought_J"] = e0 - sum(s.energy().values())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tau", type=float, default=1.7, help="friction torque per real joint (N*m)")
    ap.add_argument("--horizon", type=float, default=2.0, help="simulated time per landing (s)")
    a = ap.parse_args()
    base = Model.default()
    readings = {
        "pair (joints_per_planar_leg = 2)": base,
        "single (joints_per_planar_leg = 1)": base.with_params(joints_per_planar_leg=1.0),
        "pair, without eq. 3 (downhill torque growth)": base.without("downhill_torque_growth"),
    }
    for label, model in readings.items():
        print(f"\n## {label}, tau = {a.tau} N*m per joint, rotors off; shares of the energy dissipated")
        print("| slope | speed | energy J | joint friction | flex damper | end stop | ground damper | feet |")
        print("|---|---|---|---|---|---|---|---|")
        sums = dict.fromkeys(SHOWN, 0.0)
        n = 0
        for slope in (0, 10, 20, 30, 40):
            for speed in (1.0, 2.0, 3.0):
                r = split(model, slope, speed, a.tau, a.horizon)
                n += 1
                for k in SHOWN:
                    sums[k] += r[k]
                cells = " | ".join(f"{100 * r[k]:.0f} %" for k in SHOWN)
                print(f"| {slope}° | {speed:.0f} m/s | {r['total_J']:.2f} | {cells} |")
        print("| mean | | | " + " | ".join(f"{100 * sums[k] / n:.0f} %" for k in SHOWN) + " |")


if __name__ == "__main__":
    main()
