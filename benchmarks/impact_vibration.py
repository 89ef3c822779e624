"""How often the on-board script's impact rule reverses in the air under an F450's vibration, with
the shipped settings (docs/onboard-script.md, "The impact"), for the script and, in the same run,
another version of it to compare with.

The accelerometer is tests/firmware/vibration.py's (rotor lines and airflow at ArduPilot's
vibration limits, ``--scales`` times them; a 40 Hz frame mode ringing down after the cut at
``--amplitudes`` m/s² after the filter). Each cut falls through the missed-impact bound with no
contact: any reverse thrust is in the air.

    git show b82d2fd~4:firmware_params/scripts/slopelander.lua > /tmp/contract4.lua
    python3 benchmarks/impact_vibration.py --compare-with /tmp/contract4.lua --cuts 60
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT), str(ROOT / "tests" / "firmware")]

import vibration  # noqa: E402
from test_script_vibration import fly, from_flight  # noqa: E402

SCRIPT = ROOT / "firmware_params" / "scripts" / "slopelander.lua"


def rotor_fires(script: Path, scale: float, cuts: int) -> list[tuple[int, int]]:
    fired = []
    for seed in range(cuts):
        _, rvt = fly(from_flight(vibration.flight(2.0, 2.6, seed=seed, scale=scale)), script=script)
        if rvt is not None:
            fired.append((seed, rvt))
    return fired


def ringing_fires(script: Path, amplitude: float) -> list[tuple[int, int]]:
    fired = []
    for phase in range(0, 360, 30):
        f = vibration.ringing(1.5, 2.0, amplitude=amplitude, phase=math.radians(phase))
        _, rvt = fly(from_flight(f), script=script)
        if rvt is not None:
            fired.append((phase, rvt))
    return fired


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--script", type=Path, default=SCRIPT, help="the script measured (default: shipped)")
    ap.add_argument("--compare-with", type=Path, default=None, help="another script, measured alike")
    ap.add_argument("--cuts", type=int, default=20, help="cuts per vibration level (seeds)")
    ap.add_argument("--scales", default="1,1.25,1.5,1.75,2", help="times ArduPilot's limits")
    ap.add_argument("--amplitudes", default="7,8.5,10", help="frame mode, m/s² after the filter")
    a = ap.parse_args(argv)
    scripts = [a.script] + ([a.compare_with] if a.compare_with else [])
    for s in scripts:
        if not s.is_file():
            ap.error(f"{s}: no such script")
    t0 = time.monotonic()
    print("accelerometer | " + " | ".join(str(s) for s in scripts))
    for scale in (float(x) for x in a.scales.split(",")):
        cells = []
        for s in scripts:
            fired = rotor_fires(s, scale, a.cuts)
            cells.append(f"{len(fired)}/{a.cuts} reversed in the air (seed, ms after the cut: {fired})")
        print(f"rotor lines and airflow x{scale:g} | " + " | ".join(cells), flush=True)
    for amp in (float(x) for x in a.amplitudes.split(",")):
        cells = []
        for s in scripts:
            fired = ringing_fires(s, amp)
            cells.append(f"{len(fired)}/12 phases reversed in the air ({fired})")
        print(f"40 Hz frame mode {amp:g} m/s^2 | " + " | ".join(cells), flush=True)
    print(f"({time.monotonic() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
