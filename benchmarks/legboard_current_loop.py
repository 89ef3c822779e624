"""The leg-board firmware's clamp on MicroPython: step response of the current loop, and the torque
error against what the landing model asks for.

The firmware (``firmware/legboard``) runs on the real MicroPython with the plant model behind
its HAL. The model's requests are the paper's four torque levels (0.56, 1.1, 1.7, 2.3 N·m); each
becomes a current target through the plant's own curve (a perfect calibration), so the error
left is the firmware's and the mechanism's: torque held − torque asked, after the board reports
HOLDING. Two cases over ``--seeds`` noise seeds: a clamp from loose (a landing's preset) and a
step of the target while holding (1.1 → 1.7 N·m). For the step, the clamping current (the
current the clamp force corresponds to, I₀ + g·F) is traced every tick: 10–90 % rise time,
overshoot above the target, time to HOLDING. The same scenario on this CPython is the peer
(the plant draws the same noise on both, so the numbers should agree).

    SLOPELANDER_MICROPYTHON=/path/to/micropython python3 benchmarks/legboard_current_loop.py --seeds 8
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "firmware" / "legboard"
WIRE = ROOT / "src" / "slopelander" / "legs"

SCENARIO = """
import json
from legfw.host import HostBoard

LEVELS = (0.56, 1.1, 1.7, 2.3)


def target(b, leg, tau):
    p = b.plant.p
    return round((p.i_no_load + p.amps_per_newton() * tau / (p.torque_per_newton() * p.mu[leg])) * 1000)


def clamp_ma(b, leg):
    p = b.plant.p
    return (p.i_no_load + p.amps_per_newton() * b.plant.legs[leg].force()) * 1000


def from_loose(seed):
    b = HostBoard(seed=seed)
    t0 = b.time_s
    want = [target(b, leg, LEVELS[leg]) for leg in range(4)]
    for leg in range(4):
        b.fw.legs[leg].set_friction(want[leg])
    held = [None] * 4
    while b.time_s - t0 < 20 and None in held:
        b.advance(b.time_s + 0.004)
        for leg in range(4):
            if held[leg] is None and b.fw.legs[leg].state == 3:
                held[leg] = b.time_s - t0
    b.advance(b.time_s + 2.0)
    return {
        "held_s": held,
        "torque_error_nm": [b.plant.legs[leg].friction_torque() - LEVELS[leg] for leg in range(4)],
        "clamp_error_ma": [clamp_ma(b, leg) - want[leg] for leg in range(4)],
    }


def step(seed):
    b = HostBoard(seed=seed)
    lo = [target(b, leg, 1.1) for leg in range(4)]
    hi = [target(b, leg, 1.7) for leg in range(4)]
    for leg in range(4):
        b.fw.legs[leg].set_friction(lo[leg])
    b.advance(b.time_s + 9.9)
    b.advance(b.time_s + 3.0)
    before = [clamp_ma(b, leg) for leg in range(4)]
    for leg in range(4):
        b.fw.legs[leg].set_friction(hi[leg])
    t0 = b.time_s
    trace = []
    held = [None] * 4
    t10 = [None] * 4
    t90 = [None] * 4
    peak = list(before)
    while b.time_s - t0 < 8.0:
        b.advance(b.time_s + 0.004)
        t = b.time_s - t0
        for leg in range(4):
            c = clamp_ma(b, leg)
            peak[leg] = max(peak[leg], c)
            if t10[leg] is None and c >= before[leg] + 0.1 * (hi[leg] - before[leg]):
                t10[leg] = t
            if t90[leg] is None and c >= before[leg] + 0.9 * (hi[leg] - before[leg]):
                t90[leg] = t
            if held[leg] is None and b.fw.legs[leg].state == 3:
                held[leg] = t
        if seed == 0 and len(trace) < 40 and t >= 0.2 * len(trace):
            trace.append([t, clamp_ma(b, 2), b.fw.legs[2].i_filt / 1000])
    return {
        "held_s": held,
        "rise_s": [t90[leg] - t10[leg] for leg in range(4)],
        "overshoot_ma": [peak[leg] - hi[leg] for leg in range(4)],
        "torque_error_nm": [b.plant.legs[leg].friction_torque() - 1.7 for leg in range(4)],
        "trace": trace,
    }


import sys

seeds = SEEDS if "SEEDS" in globals() else json.loads(sys.stdin.readline())
for seed in seeds:  # a line per seed: one big reply would not fit a Pico's heap
    print(json.dumps({"from_loose": from_loose(seed), "step": step(seed)}))
"""


def on_micropython(binary: str, seeds: list[int]) -> tuple[dict, float]:
    prelude = f"import sys\nsys.path.append({str(WIRE)!r})\nsys.path.append({str(FIRMWARE)!r})\n"
    t0 = time.perf_counter()
    done = subprocess.run(
        [binary, "-X", "heapsize=192K", "-c", prelude + SCENARIO],
        input=json.dumps(seeds) + "\n",
        capture_output=True,
        text=True,
        timeout=1800,
        check=True,
    )
    return _gather(done.stdout.splitlines()), time.perf_counter() - t0


def _gather(lines: list[str]) -> dict:
    runs = [json.loads(line) for line in lines if line.strip()]
    return {"from_loose": [r["from_loose"] for r in runs], "step": [r["step"] for r in runs]}


def on_cpython(seeds: list[int]) -> tuple[dict, float]:
    sys.path[:0] = [str(ROOT / "src"), str(FIRMWARE)]
    out: list[str] = []
    t0 = time.perf_counter()
    exec(SCENARIO, {"SEEDS": seeds, "print": out.append})
    return _gather(out), time.perf_counter() - t0


def summary(res: dict) -> dict:
    loose = res["from_loose"]
    steps = res["step"]
    return {
        "loose_held_s": [t for r in loose for t in r["held_s"]],
        "loose_torque_err": [e for r in loose for e in r["torque_error_nm"]],
        "loose_clamp_err_ma": [e for r in loose for e in r["clamp_error_ma"]],
        "step_rise_s": [x for r in steps for x in r["rise_s"]],
        "step_overshoot_ma": [x for r in steps for x in r["overshoot_ma"]],
        "step_held_s": [x for r in steps for x in r["held_s"]],
        "step_torque_err": [x for r in steps for x in r["torque_error_nm"]],
    }


def _fmt(xs: list[float], unit: str, digits: int = 3) -> str:
    m = statistics.mean(xs)
    sd = statistics.pstdev(xs)
    return (
        f"mean {m:+.{digits}f} sd {sd:.{digits}f} min {min(xs):+.{digits}f} max {max(xs):+.{digits}f} {unit}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=8)
    a = ap.parse_args()
    binary = os.environ.get("SLOPELANDER_MICROPYTHON")
    if not binary:
        raise SystemExit("set SLOPELANDER_MICROPYTHON to a MicroPython unix-port binary")
    seeds = list(range(a.seeds))
    mp, mp_s = on_micropython(binary, seeds)
    cp, cp_s = on_cpython(seeds)
    print(f"leg-board clamp, {a.seeds} seeds x 4 legs, load average {os.getloadavg()[0]:.1f}")
    for name, res, secs in (("MicroPython", mp, mp_s), ("CPython (peer)", cp, cp_s)):
        s = summary(res)
        print(f"firmware on {name} ({secs:.1f} s of CPU and wall for the scenario):")
        print(f"  from loose to 0.56/1.1/1.7/2.3 N·m: HOLDING after {_fmt(s['loose_held_s'], 's', 2)}")
        print(f"    torque held - asked: {_fmt(s['loose_torque_err'], 'N·m')}")
        print(f"    clamping current - target: {_fmt(s['loose_clamp_err_ma'], 'mA', 2)}")
        print(f"  step 1.1 -> 1.7 N·m while holding: 10-90 % rise {_fmt(s['step_rise_s'], 's', 2)}")
        print(f"    overshoot of the clamping current: {_fmt(s['step_overshoot_ma'], 'mA', 2)}")
        print(f"    HOLDING after {_fmt(s['step_held_s'], 's', 2)}")
        print(f"    torque held - asked: {_fmt(s['step_torque_err'], 'N·m')}")
    same = summary(mp) == summary(cp)
    print(f"MicroPython and CPython give the same numbers: {same}")
    print("step trace on MicroPython, seed 0, leg 2: time s, clamping current mA, measured (filtered) mA")
    for t, clamp, measured in mp["step"][0]["trace"]:
        print(f"  {t:5.2f}  {clamp:7.2f}  {measured:7.2f}")


if __name__ == "__main__":
    main()
