"""How fast ``slopelander import`` reads and solves a 1-minute, 200 Hz, 40-marker C3D take.

    python benchmarks/import_speed.py [--repeats N]

The take: the shipped example's body cluster (4 markers) and roof (4) plus 32 other markers
(a wand, people walking), 12 000 frames; one drop at its start (free fall, then the body
stopped by the roof), the vehicle at rest for the remaining minute. Printed beside the import:
the same file read by the ``c3d`` package alone, by ``ezc3d`` (a C++ reader, the peer), and
the file's bytes read by numpy (the floor no reader beats), all measured in this run.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]

from slopelander.ident.mocap.formats import read_c3d, write_c3d  # noqa: E402
from slopelander.ident.mocap.importer import import_takes  # noqa: E402
from slopelander.ident.truth.lab import LabTake, Occlusion, observe  # noqa: E402

RATE = 200.0
SECONDS = 60.0


def landing(t: np.ndarray) -> np.ndarray:
    """x, z, pitch of a body falling at 2 m/s onto a 20 deg roof, stopped within ~50 ms."""
    z0 = 0.35
    z = np.where(
        t < 0, z0 - 2.0 * t - 4.905 * t * t, z0 - 0.2 * (1 - np.exp(-np.clip(t, 0, None) / 0.025)) * 0.25
    )
    pitch = np.where(t < 0, 0.0, -0.05 * (1 - np.exp(-np.clip(t, 0, None) / 0.04)))
    return np.column_stack([np.zeros_like(t), z, pitch])


def make_take(folder: Path) -> tuple[Path, Path]:
    rng = np.random.default_rng(0)
    t = np.arange(round(SECONDS * RATE)) / RATE - 0.15
    lab = LabTake(occlusions=(Occlusion(("TOP",), 0.1, 0.05),))
    labels, pts = observe(landing(t), t, 20.0, lab, rng)
    walkers = np.cumsum(rng.normal(0.0, 0.002, (len(t), 32, 3)), axis=0) + rng.uniform(-2, 2, (1, 32, 3))
    walkers[rng.uniform(size=walkers.shape[:2]) < 0.02] = np.nan
    labels += [f"OTHER{i:02d}" for i in range(32)]
    take = folder / "minute.c3d"
    write_c3d(take, labels, np.concatenate([pts, walkers], axis=1), RATE)
    markers = folder / "markers.yaml"
    markers.write_text(
        (ROOT / "docs/examples/mocap/markers.yaml").read_text().replace("takes: takes.csv", "")
    )
    return take, markers


def best_of(n: int, fn) -> float:
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        take, markers = make_take(folder)
        tk = read_c3d(take)
        size = take.stat().st_size / 1e6
        print(f"take: {tk.frames} frames x {len(tk.labels)} markers at {tk.rate:g} Hz, {size:.1f} MB")
        runs = iter(range(10**6))
        t_import = best_of(args.repeats, lambda: import_takes([take], markers, folder / f"out{next(runs)}"))
        t_c3d = best_of(args.repeats, lambda: read_c3d(take))
        try:
            import ezc3d

            t_ez = best_of(args.repeats, lambda: ezc3d.c3d(str(take)))
        except ModuleNotFoundError:
            t_ez = math.nan
        t_bytes = best_of(args.repeats, lambda: np.fromfile(take, dtype=np.float32))
    print(f"slopelander import (read, fit, write): {t_import:.3f} s  ({SECONDS / t_import:.0f}x real time)")
    print(f"  of which reading with the c3d package: {t_c3d:.3f} s")
    print(f"  peer: ezc3d reading the same file:     {t_ez:.3f} s")
    print(f"  floor: numpy reading its bytes:        {t_bytes:.4f} s")
    print(f"(best of {args.repeats} each, this run)")


if __name__ == "__main__":
    main()
