"""CPU time of one prediction of a fit (``Problem.residuals`` over 10 drops), split into the
compiled integrator's call and the Python work around it.

Prints, per prediction: the total, the integrator's call (numba's unboxing of its arguments
included) and the rest; and the rest alone, measured with the integrator replaced by a replay of
its recorded output (the Python work without the caches the integrator's run leaves cold).

    python benchmarks/predict_speed.py [--points 30] [--repeats 3] [--against OTHER_CHECKOUT]

With ``--against``, the same measurement of another checkout (e.g. a git worktree of an older
commit) runs interleaved with this one's, each in its own process, and the ratios are printed:
on a shared machine only figures measured side by side compare.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def measure(points: int, repeats: int) -> tuple[float, float, float]:
    """(total, integrator call, replayed rest) in CPU seconds per prediction."""
    import numpy as np

    from slopelander.ident.compare import state_ranges
    from slopelander.ident.fit import Problem, resolve_params
    from slopelander.ident.synth import NoiseModel, paper_drops, synthesize
    from slopelander.model import Model, landing

    clock = time.process_time
    truth = Model.default().without("downhill_torque_growth", "downhill_friction_growth")
    drops = synthesize(truth, paper_drops(10, seed=0), NoiseModel(), seed=1, duration=0.6)
    prob = Problem(truth, drops, resolve_params(truth), state_ranges(drops))
    rng = np.random.default_rng(7)
    us = [rng.uniform(0.3, 0.7, len(prob.params)) for _ in range(points)]
    prob.residuals(us[0])  # compile or load
    call = landing.call
    spent, recorded, nxt = [0.0], [], [0]

    def timed(disp, *args):
        t0 = clock()
        n = call(disp, *args)
        spent[0] += clock() - t0
        return n

    def record(disp, *args):
        n = call(disp, *args)
        recorded.append((n, args[7][:n].copy(), args[9].copy()))
        return n

    def replay(disp, *args):
        n, rec, res = recorded[nxt[0]]
        nxt[0] += 1
        args[7][:n], args[9][:] = rec, res
        return n

    def run(through) -> float:
        landing.call = through
        t0 = clock()
        for u in us:
            prob.residuals(u)
        return (clock() - t0) / (10 * len(us))

    totals, calls, rests = [], [], []
    try:
        run(record)
        for _ in range(repeats):
            spent[0] = 0.0
            totals.append(run(timed))
            calls.append(spent[0] / (10 * len(us)))
            nxt[0] = 0
            rests.append(run(replay))
    finally:
        landing.call = call
    return float(np.median(totals)), float(np.median(calls)), float(np.median(rests))


def run_in(checkout: Path, points: int, repeats: int) -> tuple[float, float, float]:
    code = (
        f"import sys; sys.path[:0] = [{str(checkout / 'src')!r}, {str(checkout)!r}]\n"
        f"sys.path.insert(0, {str(Path(__file__).parent)!r}); import predict_speed as b\n"
        f"print(*b.measure({points}, {repeats}))"
    )
    env = {**os.environ, "PYTHONPATH": ""}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    total, kernel, rest = (float(x) for x in out.stdout.split()[-3:])
    return total, kernel, rest


def show(label: str, r: tuple[float, float, float]) -> None:
    total, kernel, rest = (1e6 * x for x in r)
    print(
        f"{label}: {total:.0f} us a prediction, integrator call {kernel:.0f} us, "
        f"the rest {total - kernel:.0f} us (replayed: {rest:.0f} us)",
        flush=True,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=30, help="parameter points (10 drops each)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds with --against")
    ap.add_argument("--against", type=Path, help="another checkout to compare with")
    args = ap.parse_args()
    if args.against is None:
        show("this checkout", run_in(ROOT, args.points, args.repeats))
        return
    ratios = []
    for i in range(args.rounds):
        other = run_in(args.against.resolve(), args.points, args.repeats)
        this = run_in(ROOT, args.points, args.repeats)
        show(f"round {i + 1} other", other)
        show(f"round {i + 1} this ", this)
        ratios.append(((this[0] - this[1]) / (other[0] - other[1]), this[2] / other[2], this[0] / other[0]))
    for i, (rest, replayed, total) in enumerate(ratios):
        print(f"round {i + 1}: this/other  rest {rest:.2f}  replayed rest {replayed:.2f}  total {total:.2f}")


if __name__ == "__main__":
    main()
