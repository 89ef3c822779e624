"""The compiled model's speed as ratios measured in one run: against a past commit's integrator,
against the MuJoCo peer, and with a user effect in a seam.

This machine's speed moves 3-4x with its hours, so an absolute rate says little; a ratio to a
reference timed in the same process, the two taking turns, shows a regression. On the same
drops (200 by default: slopes 0-45 deg, impact speeds 1-3 m/s, two torque levels, no thrust),
each on one core, in rounds that alternate them:

* today's model as shipped, and as matched to the peer (``matched_model``);
* the same model as a past commit had it (``--past``, default 67501ca, the last one before the
  seam table; extracted from git into a cache directory by ``past_model.py``);
* today's model with a user effect in a seam (a joint-torque law that returns the torque it is
  given): what a user's effect costs over the built-in model;
* the MuJoCo peer (``--no-peer`` to skip): at the same simulated time (MuJoCo's bare
  ``mj_step`` for exactly the seconds the model simulated, drop by drop, no stop checks: the
  cheapest MuJoCo can be) and stopping at rest (each by its own criterion).

Every landing runs either to the 2 s horizon (a flip ends it) or until at rest. Prints landings
per CPU-second (the median over rounds; wall clock beside it), the ratios per round, and how
far today's and the past commit's results agree.

Usage: python benchmarks/model_ratio.py [--rounds 3] [--past 67501ca] [--no-peer] [--slopes 20]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from past_model import load_past_model

from slopelander import model as today
from slopelander.model import kernel as k
from slopelander.model.effects import UserEffect


@numba.njit
def same_torque(t, st, ctx, up, leg, angle, rate, tau):  # pragma: no cover - compiled
    """A joint-torque law that changes nothing: the seam path's own cost."""
    return tau


SAME_TORQUE = UserEffect("same_torque", "returns the slip torque it is given", joint_torque=same_torque)


def drops(mod, slopes: int) -> np.ndarray:
    g = mod.condition_grid(
        slope_deg=np.linspace(0.0, 45.0, slopes),
        speed=np.array([1.0, 1.5, 2.0, 2.5, 3.0]),
        tau_up=np.array([1.1, 2.3]),
    )
    g["tau_down"] = g["tau_up"]
    g["reverse_percent"] = 0.0
    return g


def timed(fn, *args, **kwargs) -> tuple[float, float, object]:
    """CPU seconds, wall seconds and the result of ``fn(*args, **kwargs)``."""
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn(*args, **kwargs)
    return time.process_time() - c0, time.perf_counter() - w0, out


def peer_bare(peer, conds: np.ndarray, seconds: np.ndarray) -> None:
    """MuJoCo's own stepping, landing by landing, for the given simulated seconds: no stop
    checks, no outcome (the cheapest MuJoCo can run these drops)."""
    rows = conds.view(np.float64).reshape(len(conds), k.N_COND)
    for i in range(len(rows)):
        peer.start(rows[i])
        peer._mj.mj_step(peer.mjmodel, peer.data, nstep=round(seconds[i] / peer.settings.timestep))


def simulated_seconds(res: np.ndarray, horizon: float, stop_at_rest: bool) -> np.ndarray:
    """Seconds each landing was simulated for: to rest (the settle time plus the criterion's
    hold), a flip or a slide past the limit when stopping at rest; else the horizon unless a
    flip ended it."""
    flipped = res["outcome"] == today.Outcome.FLIP
    if stop_at_rest:
        return res["t_end"]
    return np.where(flipped, res["t_end"], horizon)


def agreement(a: np.ndarray, b: np.ndarray) -> str:
    same = int(np.sum(a["outcome"] == b["outcome"]))
    worst = {
        n: float(np.nanmax(np.abs(a[n] - b[n])))
        for n in ("compression_up", "compression_down", "slide", "min_pitch_deg")
    }
    identical = all(np.array_equal(a[n], b[n], equal_nan=True) for n in a.dtype.names)
    return (
        f"same outcome class {same}/{len(a)}; largest |difference|: compression "
        f"{max(worst['compression_up'], worst['compression_down']):.2e}, slide {worst['slide']:.2e} m, "
        f"most negative pitch {worst['min_pitch_deg']:.2e} deg; "
        f"{'bit-identical' if identical else 'not bit-identical'}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--past", default="67501ca", help="the commit to compare with ('' to skip)")
    ap.add_argument("--no-peer", action="store_true", help="skip the MuJoCo peer")
    ap.add_argument("--slopes", type=int, default=20, help="slopes 0-45 deg; x 10 drops")
    args = ap.parse_args()

    load = os.getloadavg()
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average "
        f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} at start; numba {numba.__version__}; one core each"
    )
    conds = drops(today, args.slopes)
    n = len(conds)
    shipped = today.Model.default()
    horizon = shipped.criteria.horizon
    from slopelander.peers.mujoco_drop import MujocoDrop, matched_model

    matched = matched_model(shipped)
    variants: dict[str, tuple] = {
        "today, as shipped": (today, shipped, conds),
        "today, matched": (today, matched, conds),
        "today + a user effect": (today, shipped.with_user_effect(SAME_TORQUE), conds),
    }
    if args.past:
        past = load_past_model(args.past)
        variants[f"{args.past}, as shipped"] = (past, past.Model.default(), drops(past, args.slopes))
    print(
        f"{n} drops: slopes 0-45 deg ({args.slopes}), speeds 1-3 m/s (5), torques 1.1 and 2.3 N*m, no thrust"
    )
    for mod, model, c in variants.values():  # compile or load the caches outside the timing
        mod.simulate_batch(c[:2], model)
        mod.simulate_batch(c[:2], model, stop_at_rest=False)
    peer = None if args.no_peer else MujocoDrop(matched)
    numba.set_num_threads(1)

    modes = (("2 s", False), ("rest", True))
    cpu: dict[tuple[str, str], list[float]] = {}
    wall: dict[tuple[str, str], list[float]] = {}
    results: dict[tuple[str, str], np.ndarray] = {}
    for _ in range(args.rounds):
        for name, (mod, model, c) in variants.items():
            for mode, rest in modes:
                tc, tw, res = timed(mod.simulate_batch, c, model, stop_at_rest=rest)
                cpu.setdefault((name, mode), []).append(tc)
                wall.setdefault((name, mode), []).append(tw)
                results[(name, mode)] = res
        if peer is not None:
            seconds = simulated_seconds(results[("today, matched", "2 s")], horizon, False)
            for mode, (fn, fargs) in (
                ("2 s", (peer_bare, (peer, conds, seconds))),
                ("rest", (peer.run_batch, (conds,))),
            ):
                tc, tw, res = timed(fn, *fargs)
                cpu.setdefault(("MuJoCo", mode), []).append(tc)
                wall.setdefault(("MuJoCo", mode), []).append(tw)
                if res is not None:
                    results[("MuJoCo", mode)] = res

    def rate(name: str, mode: str) -> float:
        return n / float(np.median(cpu[(name, mode)]))

    def per_round(a: str, b: str, mode: str) -> str:
        return ", ".join(f"{y / x:.2f}" for x, y in zip(cpu[(a, mode)], cpu[(b, mode)], strict=True))

    print("\nlandings per CPU-second (median of rounds; wall clock in brackets)")
    names = list(variants) + ([] if peer is None else ["MuJoCo"])
    for mode, _ in modes:
        cells = [
            f"{nm} {rate(nm, mode):7.1f} ({n / float(np.median(wall[(nm, mode)])):6.1f})" for nm in names
        ]
        print(f"  {mode:<4}: " + "   ".join(cells))
    print("\nratios of landings per CPU-second (median; per round)")
    for mode, rest in modes:
        if args.past:
            ref = f"{args.past}, as shipped"
            print(
                f"  {mode:<4} today / {args.past}, as shipped: "
                f"{rate('today, as shipped', mode) / rate(ref, mode):5.2f}  "
                f"({per_round('today, as shipped', ref, mode)})"
            )
        print(
            f"  {mode:<4} today / today + a user effect: "
            f"{rate('today, as shipped', mode) / rate('today + a user effect', mode):5.2f}  "
            f"({per_round('today, as shipped', 'today + a user effect', mode)})"
        )
        if peer is not None:
            goal = 30 if not rest else 60
            ours = simulated_seconds(results[("today, matched", mode)], horizon, rest).mean()
            theirs = float(results[("MuJoCo", "rest")]["t_end"].mean()) if rest else ours
            ratio = rate("today, matched", mode) / rate("MuJoCo", mode)
            print(
                f"  {mode:<4} today (matched) / MuJoCo: {ratio:5.1f}x "
                f"({per_round('today, matched', 'MuJoCo', mode)}; goal >= {goal}x); simulated s per landing "
                f"model {ours:.2f}, MuJoCo {theirs:.2f}"
            )
    if args.past:
        print("\nagreement, today vs " + args.past + " (as shipped)")
        for mode, _ in modes:
            print(
                f"  {mode:<4}: "
                + agreement(results[("today, as shipped", mode)], results[(f"{args.past}, as shipped", mode)])
            )
    for mode, _ in modes:
        print(
            f"  {mode:<4}: today vs today + a user effect: "
            + agreement(results[("today, as shipped", mode)], results[("today + a user effect", mode)])
        )
    load = os.getloadavg()
    print(f"\nload average at the end {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f}")


if __name__ == "__main__":
    main()
