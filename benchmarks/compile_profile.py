"""Where the model's first compile spends its time: per compiled function (numba's own compile
events) and per compiler phase (cProfile over numba's passes), in a fresh numba cache.

    python benchmarks/compile_profile.py             # this checkout
    python benchmarks/compile_profile.py --root DIR  # another checkout's src/

The phases are cumulative times under cProfile (which slows the compile about threefold): read
them as shares, not seconds. The per-function times are wall seconds without the profiler and
nest (a caller's time includes the callees compiled for it).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

PROBE = textwrap.dedent(
    """
    import cProfile, pstats, sys, time
    from numba.core import event
    from slopelander.model import LandingConditions, simulate
    c = LandingConditions(slope_deg=20, speed=2)
    mode = sys.argv[1]
    if mode == "events":
        with event.install_recorder("numba:compile") as rec:
            t0, c0 = time.perf_counter(), time.process_time()
            simulate(c, full_horizon=False)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            print(f"first landing: {wall:.1f} s wall, {cpu:.1f} s CPU")
        starts, rows = {}, []
        for ts, ev in rec.buffer:
            key = id(ev.data["dispatcher"]), str(ev.data["args"])
            if ev.is_start:
                starts[key] = ts
            else:
                f = ev.data["dispatcher"].py_func
                rows.append((ts - starts.pop(key), f"{f.__module__}.{f.__qualname__}"))
        print(f"{len(rows)} functions compiled; the slowest (s, nested):")
        for s, name in sorted(rows, reverse=True)[:8]:
            print(f"  {s:6.2f}  {name}")
    else:
        prof = cProfile.Profile()
        prof.runcall(simulate, c, full_horizon=False)
        st = pstats.Stats(prof)
        total = max(v[3] for v in st.stats.values())
        phases = {  # nested: the inlining and lowering shares lie within type inference's
            "type inference (with the nested compiles it starts)": ("typeinfer.py", "propagate"),
            "inlining: copying the callee's IR": ("inline_closurecall.py", "copy_ir"),
            "inlining (all)": ("inline_closurecall.py", "inline_function"),
            "lowering to LLVM IR": ("lowering.py", "lower"),
            "LLVM (llvmlite calls)": ("ffi.py", "__call__"),
        }
        print("compiler phases, share of the profiled first landing:")
        for label, (file, func) in phases.items():
            hits = [v[3] for k, v in st.stats.items() if k[0].endswith(file) and k[2] == func]
            cum = max(hits, default=0.0)
            print(f"  {100 * cum / total:5.1f} %  {label}")
    """
)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = Path(__file__).resolve().parents[1]
    ap.add_argument("--root", type=Path, default=here, help="checkout to measure")
    args = ap.parse_args()
    root = args.root.resolve()
    print(f"{root}: load average {'/'.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    for mode in ("events", "phases"):
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, PYTHONPATH=str(root / "src"), PYTHONWARNINGS="ignore", NUMBA_CACHE_DIR=tmp)
            r = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True)
            if r.returncode:
                print(r.stderr, file=sys.stderr)
                return r.returncode
            print(r.stdout, end="")
    print(f"load average {'/'.join(f'{x:.1f}' for x in os.getloadavg())} after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
