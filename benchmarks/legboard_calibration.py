"""Calibration recovery on the simulated board: the fitted curve against the hidden one, over
repeated calibrations.

Each run starts ``python -m slopelander_sitl.legboard`` (the firmware on MicroPython when
``SLOPELANDER_MICROPYTHON`` is set) with legs that follow a hidden curve (friction coefficients,
no-load current, screw efficiency and a pressure-dependent μ that are not the shipped curve's)
and a different noise seed, and runs ``slopelander legs calibrate`` on its simulated bench. The
truth is what those legs hold when the same firmware clamps them from loose at a current (the
mean of ``--clamps`` clamps, computed in this process). Printed per run and leg: the largest
|fit − truth| over the calibrated range, the stated uncertainty (95 %), and their ratio; then
the share of all comparisons inside the stated uncertainty. The shipped (assumed) curve against
the same truth is the baseline.

    SLOPELANDER_MICROPYTHON=/path/to/micropython python3 benchmarks/legboard_calibration.py --runs 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]

import yaml  # noqa: E402

from slopelander.legs import load_calibration  # noqa: E402
from slopelander_sitl.legboard.runtime import HostBoard  # noqa: E402

HIDDEN = {"mu": [0.25, 0.29, 0.27, 0.30], "i_no_load": 0.047, "screw_efficiency": 0.22, "mu_slope": -0.05}
MASSES = "0.2,0.5,0.9,1.5"
CURRENTS = range(62, 156, 6)


def truth(clamps: int) -> dict[int, dict[int, float]]:
    """Mean torque each hidden leg holds when clamped from loose at each current."""
    out: dict[int, dict[int, float]] = {leg: {} for leg in range(4)}
    for ma in CURRENTS:
        sums = [0.0] * 4
        for seed in range(clamps):
            b = HostBoard(plant=dict(HIDDEN, mu=tuple(HIDDEN["mu"])), seed=1000 + seed)
            for leg in range(4):
                b.fw.legs[leg].set_friction(ma)
            for _ in range(3):
                b.advance(b.time_s + 9.0)
            for leg in range(4):
                sums[leg] += b.plant.legs[leg].friction_torque()
        for leg in range(4):
            out[leg][ma] = sums[leg] / clamps
    return out


def calibrate(seed: int, directory: Path) -> tuple[Path, str, float]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "src"), str(ROOT)]))
    link = directory / "legs"
    (directory / "plant.json").write_text(json.dumps(HIDDEN))
    board = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "slopelander_sitl.legboard",
            "--link",
            str(link),
            "--clock",
            "external",
            "--plant",
            str(directory / "plant.json"),
            "--seed",
            str(seed),
        ],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    ready = board.stdout.readline()
    runtime = ready.split("runtime=")[-1].strip()
    out = directory / "cal.yaml"
    t0 = time.perf_counter()
    try:
        subprocess.run(
            [
                sys.executable,
                "-m",
                "slopelander.cli",
                "legs",
                "calibrate",
                "--legs-port",
                str(link),
                "--masses",
                MASSES,
                "--lever",
                "0.2",
                "--repeats",
                "2",
                "--out",
                str(out),
                "--bench",
                f"sim:{link}.ctl",
            ],
            check=True,
            capture_output=True,
            env=env,
            timeout=3600,
        )
    finally:
        board.terminate()
        board.wait(10)
    return out, runtime, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--clamps", type=int, default=6, help="clamps averaged for the truth at each current")
    a = ap.parse_args()
    true = truth(a.clamps)
    shipped = load_calibration()
    ratios_all, rows = [], []
    shipped_worst = max(abs(shipped.torque(leg, ma) - t) for leg in range(4) for ma, t in true[leg].items())
    for run in range(a.runs):
        with tempfile.TemporaryDirectory(prefix="legcal-") as d:
            path, runtime, secs = calibrate(run, Path(d))
            cal = load_calibration(path)
            unc = [e["uncertainty_nm"] for e in yaml.safe_load(path.read_text())["legs"]]
        for leg in range(4):
            lo, hi = cal.legs[leg].current_ma[0], cal.legs[leg].current_ma[-1]
            errs = [abs(cal.torque(leg, ma) - t) for ma, t in true[leg].items() if lo <= ma <= hi]
            ratios_all += [e / unc[leg] for e in errs]
            rows.append((run, leg, max(errs), unc[leg], max(errs) / unc[leg], runtime, secs))
    print(
        f"calibration recovery: {a.runs} calibrations of hidden legs (masses {MASSES} kg on 0.2 m, "
        f"2 repeats), truth = mean of {a.clamps} clamps, load average {os.getloadavg()[0]:.1f}"
    )
    print("run leg  largest |fit-truth| N·m  stated ±N·m (95 %)  ratio  firmware on   wall s")
    for run, leg, err, unc, ratio, runtime, secs in rows:
        print(f"{run:3d} {leg:3d}  {err:22.4f}  {unc:18.4f}  {ratio:5.2f}  {runtime:<11}  {secs:6.0f}")
    inside = sum(r <= 1.0 for r in ratios_all) / len(ratios_all)
    print(
        f"{inside:.0%} of {len(ratios_all)} comparisons inside the stated uncertainty; largest ratio "
        f"{max(ratios_all):.2f}"
    )
    print(f"baseline, the shipped (assumed) curve on the same legs: off by up to {shipped_worst:.3f} N·m")


if __name__ == "__main__":
    main()
