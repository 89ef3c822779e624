"""What ``slopelander import`` gets back of the truth the shipped takes were made from.

    python benchmarks/import_accuracy.py [--seeds N]

1. The shipped takes (docs/examples/mocap, 0.5 mm marker noise): per take, the RMS error of
   the imported x, z and pitch against the truth at the same frames, the first-contact time
   error (and the uncertainty import printed), slope and impact-speed errors.
2. The same seven landings seen again with N other noise seeds and frame phases (the truth is
   integrated once per landing, then observed N times): the contact-time error's mean and
   spread, and how often the truth lies inside import's printed +- (a 68 % interval) and inside
   twice it (about 95 %).
3. As a reference for what the imported states cost compare: the NRMSE of the shipped model
   against the imported drops, and against the truth itself (the model's integrator and the
   truth's solve_ivp differ a little on their own).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]

from slopelander.ident.mocap.importer import import_takes  # noqa: E402
from slopelander.ident.recording import load_dataset  # noqa: E402

EXAMPLE = ROOT / "docs" / "examples" / "mocap"


def errors(drop, truth) -> tuple[float, float, float, float]:
    """RMS x, z (m), pitch (deg) at the same frames and the contact-time error (s)."""
    tc = drop.meta["quality"]["contact_time_in_take_s"]
    first = round((drop.t[0] + tc) * drop.meta["quality"]["rate_hz"])
    ref = truth.states[first : first + len(drop.t)]
    e = drop.states[:, :3] - ref[:, :3]
    rms = np.sqrt(np.nanmean(e**2, axis=0))
    return float(rms[0]), float(rms[1]), math.degrees(rms[2]), tc - (-truth.t[0])


def shipped(tmp: Path) -> None:
    out = tmp / "shipped"
    import_takes([EXAMPLE], EXAMPLE / "markers.yaml", out, keep_nonplanar=True)
    truth = {d.name: d for d in load_dataset(EXAMPLE / "truth")}
    print(
        "shipped takes: RMS error x (mm), z (mm), pitch (deg); contact error (ms) [printed +-]; slope, speed"
    )
    rows = []
    for d in load_dataset(out):
        tr = truth[d.name]
        ex, ez, ep, ec = errors(d, tr)
        sd = d.meta["quality"]["contact_sd_s"]
        rows.append((ex, ez, ep, ec))
        print(
            f"  {d.name}: {1000 * ex:.2f}, {1000 * ez:.2f}, {ep:.3f}; {1000 * ec:+.2f} [{1000 * sd:.1f}]; "
            f"{d.conditions.slope_deg - tr.conditions.slope_deg:+.2f} deg, "
            f"{100 * (d.conditions.speed / tr.conditions.speed - 1):+.1f} %"
        )
    a = np.array(rows)
    rx, rz, rp = np.sqrt(np.mean(a[:, :3] ** 2, axis=0))
    print(
        f"  all: x {1000 * rx:.2f} mm, z {1000 * rz:.2f} mm, pitch {rp:.3f} deg; "
        f"contact {1000 * a[:, 3].mean():+.2f} "
        f"+- {1000 * a[:, 3].std():.2f} ms (mean +- sd)"
    )
    from slopelander.ident.compare import compare
    from slopelander.model import Model

    model = Model.default()
    planar = [d for d in load_dataset(out) if d.meta["quality"]["planar"]]
    truths = [truth[d.name] for d in planar]
    print(
        f"compare, shipped model: NRMSE {compare(model, planar).nrmse:.4f} on the imported drops, "
        f"{compare(model, truths).nrmse:.4f} on the truth itself ({len(planar)} planar drops)"
    )


def reseeded(tmp: Path, seeds: int) -> None:
    from slopelander.ident.truth.lab import EXAMPLE as TAKES
    from slopelander.ident.truth.lab import contact_errors

    e, sd = contact_errors(tmp / "reseeded", EXAMPLE / "markers.yaml", seeds, first_seed=1000)
    inside, inside2 = int(np.sum(np.abs(e) <= sd)), int(np.sum(np.abs(e) <= 2 * sd))
    print(
        f"{seeds} noise seeds x {len(TAKES)} landings: contact error {1000 * e.mean():+.2f} ms mean, "
        f"{1000 * e.std():.2f} ms sd, |error| < 3 ms in {100 * np.mean(np.abs(e) < 0.003):.0f} %; "
        f"the truth inside the printed +- in {100 * inside / len(e):.0f} % (68 % if the +- were complete), "
        f"inside twice it in {100 * inside2 / len(e):.0f} % (about 95 %)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        shipped(Path(tmp))
        if args.seeds:
            reseeded(Path(tmp), args.seeds)


if __name__ == "__main__":
    main()
