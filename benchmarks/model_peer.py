"""The planar model against a MuJoCo peer of the same drop: landings per second and agreement.

Runs the same landings (a grid across the envelope: slopes, impact speeds, two torque levels,
no reverse thrust) through

* the compiled model (``simulate_batch``), as shipped (every effect) and as matched to what
  the MuJoCo peer can express (``matched_model``: no eq. 3/4, plain end stop, mu_s = mu_k);
* the MuJoCo peer (``slopelander.peers.mujoco_drop``),

first each on one core (numba limited to one thread, MuJoCo in this process), then each on
both cores (numba's threads, MuJoCo in two worker processes). Every landing stops once at rest
(the model's criterion) or at the 2 s horizon. Prints landings/s, the ratio, how far the two
agree (outcome class, slide, most negative pitch, peak compression: median and 90th percentile
of |difference|), and how far a vehicle standing on a 30-40 deg slope moves in 5 s in each.

Usage: python benchmarks/model_peer.py [--slope-step 5] [--speeds 1,1.5,2,2.5,3] [--taus 1.1,2.3]
                                      [--rounds 3] [--timestep-study] [--no-creep]
Needs the ``peers`` extra (pip install 'slopelander[peers]').
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import platform
import time
from dataclasses import replace

import numba
import numpy as np

from slopelander.model import Model, Outcome, condition_grid, simulate_batch
from slopelander.model import kernel as k
from slopelander.model.placement import settle_on_slope, slide_after
from slopelander.model.stepper import Stepper
from slopelander.peers.mujoco_drop import MujocoDrop, PeerSettings, matched_model

_PEER: MujocoDrop | None = None


def _init_worker(settings: PeerSettings) -> None:
    global _PEER
    _PEER = MujocoDrop(matched_model(), settings)


def _work(rows: np.ndarray) -> tuple[np.ndarray, float]:
    """The peer's outcomes for ``rows`` and the CPU seconds this process spent on them."""
    assert _PEER is not None
    c0 = time.process_time()
    res = _PEER.run_batch(rows)
    return res, time.process_time() - c0


def landing_grid(slope_step: float, speeds: list[float], taus: list[float]) -> np.ndarray:
    g = condition_grid(
        slope_deg=np.arange(0.0, 45.0 + 1e-9, slope_step),
        speed=np.array(speeds),
        tau_up=np.array(taus),
    )
    g["tau_down"] = g["tau_up"]
    g["reverse_percent"] = 0.0
    return g


def rate_of(fn, n: int, min_seconds: float = 3.0) -> tuple[float, float]:
    """Landings per wall-clock second and per CPU-second of ``fn`` (which runs n landings),
    repeated for at least ``min_seconds``."""
    reps = 0
    w0, c0 = time.perf_counter(), time.process_time()
    while True:
        fn()
        reps += 1
        t = time.perf_counter() - w0
        if t >= min_seconds:
            return reps * n / t, reps * n / (time.process_time() - c0)


def settle(model: Model, slope_deg: float, tau: float) -> Stepper:
    """A vehicle set down at rest on the slope, then left 1 s to settle (its legs splay a little
    as they take the weight)."""
    real = settle_on_slope(model, slope_deg, tau)
    slide_after(real, 1.0)
    return real


def peer_slide(peer: MujocoDrop, s: Stepper, seconds: float) -> float:
    """The peer started from the model's settled state, given 1 s to settle itself, then timed."""
    st = s.st.copy()
    st[k.S_V : k.S_V + 5] = 0.0
    peer.slide_at_rest(s.ctx, st, 1.0)
    d = peer.data
    x0, z0 = float(d.qpos[0]), float(d.qpos[1])
    peer._mj.mj_step(peer.mjmodel, d, nstep=round(seconds / peer.settings.timestep))
    a = math.radians(s.slope_deg)
    return math.cos(a) * (d.qpos[0] - x0) - math.sin(a) * (d.qpos[1] - z0)


def agreement(a: np.ndarray, b: np.ndarray) -> str:
    same = int(np.sum(a["outcome"] == b["outcome"]))
    comp = np.abs(
        np.concatenate(
            [a["compression_up"] - b["compression_up"], a["compression_down"] - b["compression_down"]]
        )
    )
    slide = np.abs(a["slide"] - b["slide"])
    pitch = np.abs(a["min_pitch_deg"] - b["min_pitch_deg"])

    def mp90(x: np.ndarray, scale: float = 1.0, fmt: str = ".3f") -> str:
        return f"{np.median(x) * scale:{fmt}} / {np.percentile(x, 90) * scale:{fmt}}"

    return (
        f"same outcome class {same}/{len(a)} ({100 * same / len(a):.0f} %); |difference| median / 90th "
        f"percentile: peak compression {mp90(comp)}, slide {mp90(slide, 1e3, '.0f')} mm, "
        f"most negative pitch {mp90(pitch, 1.0, '.1f')} deg"
    )


def confusion(a: np.ndarray, b: np.ndarray) -> str:
    lines = []
    for oa in Outcome:
        row = [int(np.sum((a["outcome"] == oa) & (b["outcome"] == ob))) for ob in Outcome]
        if sum(row):
            lines.append(
                f"    model {oa.name:<13} -> MuJoCo "
                + " ".join(f"{ob.name}:{n}" for ob, n in zip(Outcome, row, strict=True) if n)
            )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slope-step", type=float, default=5.0)
    ap.add_argument("--speeds", default="1,1.5,2,2.5,3")
    ap.add_argument("--taus", default="1.1,2.3", help="torque levels per real joint, N*m (both legs)")
    ap.add_argument("--timestep", type=float, default=PeerSettings.timestep, help="MuJoCo's step (s)")
    ap.add_argument("--no-creep", action="store_true", help="skip the vehicle-at-rest comparison")
    ap.add_argument("--rounds", type=int, default=3, help="one-core timings, taking turns")
    ap.add_argument("--timestep-study", action="store_true", help="also run MuJoCo at 0.1, 0.417 and 1 ms")
    args = ap.parse_args()
    speeds = [float(v) for v in args.speeds.split(",")]
    taus = [float(v) for v in args.taus.split(",")]
    conds = landing_grid(args.slope_step, speeds, taus)
    n = len(conds)
    settings = PeerSettings(timestep=args.timestep)
    shipped = Model.default()
    matched = matched_model(shipped)
    cores = os.cpu_count() or 1
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(
        f"machine: {platform.processor() or platform.machine()}, {cores} cores, load average "
        f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min) at start"
    )
    print(
        f"{n} landings: slopes 0-45 deg by {args.slope_step:g}, speeds {speeds} m/s, torques {taus} N*m, "
        f"no thrust; model dt {shipped.dt * 1e3:.3f} ms, MuJoCo timestep {settings.timestep * 1e3:.3f} ms; "
        f"stop at rest or at {shipped.criteria.horizon:g} s"
    )
    peer = MujocoDrop(matched, settings)
    simulate_batch(conds[:4], shipped)  # compile (or load the cache) outside the timing
    simulate_batch(conds[:4], matched)

    # one core each (wall clock, and CPU time, which other work on the machine disturbs less)
    # in rounds, the two taking turns, so that a change in the machine's load hits both
    numba.set_num_threads(1)
    ours1_shipped = rate_of(lambda: simulate_batch(conds, shipped), n)
    rounds = []
    for _ in range(args.rounds):
        a = rate_of(lambda: simulate_batch(conds, matched), n)
        w0, c0 = time.perf_counter(), time.process_time()
        res_peer = peer.run_batch(conds)
        rounds.append((a, (n / (time.perf_counter() - w0), n / (time.process_time() - c0))))
    ours1 = tuple(float(np.median([r[0][i] for r in rounds])) for i in range(2))
    peer1 = tuple(float(np.median([r[1][i] for r in rounds])) for i in range(2))
    # MuJoCo's stepping alone, for the same simulated time per landing (no stop checks at all)
    rows = conds.view(np.float64).reshape(n, k.N_COND)
    w0, c0 = time.perf_counter(), time.process_time()
    for i in range(n):
        peer.start(rows[i])
        peer._mj.mj_step(peer.mjmodel, peer.data, nstep=round(res_peer["t_end"][i] / settings.timestep))
    bare1 = (n / (time.perf_counter() - w0), n / (time.process_time() - c0))
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    res_ours = simulate_batch(conds, matched)
    res_shipped = simulate_batch(conds, shipped)

    # both cores each: numba's threads; MuJoCo in one process per core
    ours2 = rate_of(lambda: simulate_batch(conds, matched), n)
    ours2_shipped = rate_of(lambda: simulate_batch(conds, shipped), n)
    ctx = mp.get_context("spawn")
    with ctx.Pool(cores, initializer=_init_worker, initargs=(settings,)) as pool:
        pool.map(_work, [conds[:1]] * cores)  # start the workers outside the timing
        parts = [conds[i::cores] for i in range(cores)]
        w0 = time.perf_counter()
        cpu = sum(c for _, c in pool.map(_work, parts))
        peer2 = (n / (time.perf_counter() - w0), n / cpu)

    print("\nlandings per second: wall clock (per CPU-second)")
    for label, a, b, c in (
        ("one core", ours1, ours1_shipped, peer1),
        (f"{cores} cores", ours2, ours2_shipped, peer2),
    ):
        print(
            f"  {label:<9}: model (matched) {a[0]:6.0f} ({a[1]:4.0f})   model (as shipped) {b[0]:6.0f} "
            f"({b[1]:4.0f})   MuJoCo {c[0]:5.1f} ({c[1]:4.1f})"
        )
    print(f"  MuJoCo's mj_step alone, same simulated time, one core: {bare1[0]:5.1f} ({bare1[1]:4.1f})")
    for label, a, c in (("one core", ours1, peer1), (f"{cores} cores", ours2, peer2)):
        print(
            f"  ratio model (matched) / MuJoCo, {label:<9}: {a[0] / c[0]:4.0f}x wall clock, "
            f"{a[1] / c[1]:4.0f}x per CPU-second   (goal >= 30x)"
        )
    print(
        f"  ratio model (matched) / MuJoCo's mj_step alone, one core: {ours1[0] / bare1[0]:.0f}x wall clock, "
        f"{ours1[1] / bare1[1]:.0f}x per CPU-second"
    )
    per_round = ", ".join(f"{a[0] / c[0]:.0f}x / {a[1] / c[1]:.0f}x" for a, c in rounds)
    print(f"  one core, {len(rounds)} rounds (medians above), ratio per round wall / CPU: {per_round}")
    at_rest = np.isfinite(res_peer["settle_time"])
    ours_rest = np.isfinite(res_ours["settle_time"]).sum()
    print(
        f"  simulated seconds per landing: model {res_ours['t_end'].mean():.2f}, "
        f"MuJoCo {res_peer['t_end'].mean():.2f} "
        f"(MuJoCo reached rest in {at_rest.sum()}/{n}, the model in {ours_rest}/{n})"
    )

    print("\nagreement, MuJoCo vs the matched model (same physics as far as MuJoCo can express it)")
    print("  all landings : " + agreement(res_ours, res_peer))
    both = at_rest & np.isfinite(res_ours["settle_time"])
    if both.any():
        print(f"  both at rest ({both.sum()}): " + agreement(res_ours[both], res_peer[both]))
    for lo, hi in ((0, 20), (20, 35), (35, 46)):
        sel = (conds["slope_deg"] >= lo) & (conds["slope_deg"] < hi)
        print(f"  slopes {lo}-{min(hi, 45)} deg ({sel.sum()}): " + agreement(res_ours[sel], res_peer[sel]))
    print("  outcome classes, model -> MuJoCo:\n" + confusion(res_ours, res_peer))
    for name, r in (("model", res_ours), ("MuJoCo", res_peer)):
        sl = r["outcome"] == Outcome.SLID
        far = np.abs(r["slide"]) > shipped.criteria.slide_limit
        print(f"  {name} 'slid': {np.sum(sl & far)} slid over 1 m, {np.sum(sl & ~far)} still moving at 2 s")
    same = np.sum(res_shipped["outcome"] == res_ours["outcome"])
    print(f"  (the shipped model vs the matched one: same class {same}/{n})")
    lenient = MujocoDrop(matched, replace(settings, stick_speed=0.02, stick_rate=0.2)).run_batch(conds)
    print(
        "  MuJoCo with a lenient rest test (a point counts as stuck below 2 cm/s, a joint below 0.2 rad/s), "
        f"reaching rest in {np.isfinite(lenient['settle_time']).sum()}/{n}:\n    "
        + agreement(res_ours, lenient)
    )

    if args.timestep_study:
        print("\nMuJoCo's timestep: each against MuJoCo at 0.1 ms, and against the matched model")
        ref = MujocoDrop(matched, replace(settings, timestep=1e-4)).run_batch(conds)
        for h in (2.5e-4, 1 / 2400, 1e-3):
            t0 = time.perf_counter()
            r = MujocoDrop(matched, replace(settings, timestep=h)).run_batch(conds)
            rate = n / (time.perf_counter() - t0)
            print(f"  {h * 1e3:.3f} ms ({rate:.1f} landings/s): vs 0.1 ms: {agreement(ref, r)}")
            print(f"  {'':>26} vs model : {agreement(res_ours, r)}")

    if not args.no_creep:
        print(
            "\na vehicle at rest on the slope (legs 1.7 N*m, set down, 1 s to settle), then 5 s: slide (mm)"
        )
        print("  slope   model shipped (mu_s 1.2)   model matched (mu 0.8)   MuJoCo (mu 0.8)")
        for slope in (30, 34, 36, 38, 40):
            a = slide_after(settle(shipped, slope, 1.7), 5.0)
            sm = settle(matched, slope, 1.7)
            c = peer_slide(peer, sm, 5.0)
            b = slide_after(sm, 5.0)
            print(f"  {slope:3d} deg  {a * 1e3:14.4f}            {b * 1e3:14.4f}          {c * 1e3:10.1f}")
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"\nload average at the end {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f}")


if __name__ == "__main__":
    main()
