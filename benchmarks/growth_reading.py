"""How far apart the two readings of the paper's eqs. 3 and 4 put a landing: the model's (each
leg by its physical condition) and the paper's text (the downhill leg only,
``paper_downhill_growth``), over the paper's conditions.

Prints, per slope, over impact speeds and torque presets: the largest and RMS difference of the
200 Hz pitch (deg), of each leg's peak compression, of the slide (cm), and how many outcome
classes change. Both readings run in the same process on the same drops.

Usage: python benchmarks/growth_reading.py
"""

from __future__ import annotations

import itertools
import time

import numpy as np

from slopelander.model import LandingConditions, Model, simulate


def main() -> None:
    model = Model.default()
    paper = model.with_effects("paper_downhill_growth")
    print(
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; drops: speeds 1.5, 2.5 m/s; "
        "torques 1.1, 2.3 N*m (both legs); no thrust; 2 s horizon"
    )
    print("slope  pitch max|d| / rms (deg)  compression up / down max|d|  slide max|d| (cm)  outcome changes")
    for slope in (0.0, 10.0, 20.0, 30.0, 40.0):
        dp, dpr, dcu, dcd, ds, changed, n = [], [], [], [], [], 0, 0
        for speed, tau in itertools.product((1.5, 2.5), (1.1, 2.3)):
            c = LandingConditions(slope_deg=slope, speed=speed, tau_up=tau, tau_down=tau)
            a, b = simulate(c, model), simulate(c, paper)
            k = min(len(a.t), len(b.t))
            d = np.degrees(a.states[:k, 2] - b.states[:k, 2])
            dp.append(np.abs(d).max())
            dpr.append(np.sqrt(np.mean(d**2)))
            dcu.append(abs(a.result.compression_up - b.result.compression_up))
            dcd.append(abs(a.result.compression_down - b.result.compression_down))
            ds.append(100 * abs(a.result.slide - b.result.slide))
            changed += a.result.outcome != b.result.outcome
            n += 1
        print(
            f"{slope:4.0f}   {max(dp):8.3f} / {max(dpr):6.3f}            {max(dcu):6.3f} / {max(dcd):6.3f}"
            f"              {max(ds):7.2f}          {changed}/{n}"
        )


if __name__ == "__main__":
    main()
