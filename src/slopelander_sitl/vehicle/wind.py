"""Wind as a force on the body's centre: a steady part plus 1-cos gusts, all in the world x-z
plane (x toward the roof's downhill side, z up), in newtons. The vehicle hands the force to the
physics (``Stepper.set_external_force``) every physics step.

Gusts may be listed one by one or drawn from the scenario's seed (``random_gusts``), so a
scenario with random gusts flies the same way every time it runs with the same seed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

MAX_FORCE_N = 50.0  # per steady part or gust; a 1.5 kg quad's weight is about 15 N
TOTAL_LIMIT_N = 100.0  # what the physics accepts; overlapping gusts are clipped to it
MAX_RANDOM_GUSTS = 1000


@dataclass(frozen=True)
class Gust:
    """A 1-cos gust: 0 at ``t_s``, peak (fx_n, fz_n) at mid-time, 0 again at t_s + duration_s."""

    t_s: float
    duration_s: float
    fx_n: float
    fz_n: float = 0.0

    def shape(self, t: float) -> float:
        if not self.t_s <= t < self.t_s + self.duration_s:
            return 0.0
        return 0.5 * (1.0 - math.cos(2.0 * math.pi * (t - self.t_s) / self.duration_s))


@dataclass
class Wind:
    steady_fx: float = 0.0
    steady_fz: float = 0.0
    gusts: list[Gust] = field(default_factory=list)

    @property
    def calm(self) -> bool:
        return self.steady_fx == 0.0 and self.steady_fz == 0.0 and not self.gusts

    def force_at(self, t: float) -> tuple[float, float]:
        """World (fx, fz) in N at vehicle time ``t`` (s), clipped to what the physics accepts."""
        fx, fz = self.steady_fx, self.steady_fz
        for g in self.gusts:
            s = g.shape(t)
            if s:
                fx += s * g.fx_n
                fz += s * g.fz_n
        return _clip(fx), _clip(fz)


def _clip(f: float) -> float:
    return max(-TOTAL_LIMIT_N, min(TOTAL_LIMIT_N, f))


Num = Callable[[str, object, float, float], float]


def wind_from_dict(data: object, seed: int, num: Num, fail: Callable[[str], Exception]) -> Wind:
    """Parse the scenario's ``wind:`` mapping. ``num(name, value, lo, hi)`` validates a number and
    ``fail(message)`` builds the error, both naming the field as the rest of the scenario does."""
    if not isinstance(data, dict):
        raise fail("wind must be a mapping with steady, gusts and/or random_gusts")
    unknown = set(data) - {"steady", "gusts", "random_gusts"}
    if unknown:
        raise fail(f"wind: unknown field(s) {sorted(unknown)}; known: ['gusts', 'random_gusts', 'steady']")
    w = Wind()
    steady = data.get("steady", {})
    if not isinstance(steady, dict) or set(steady) - {"fx_n", "fz_n"}:
        raise fail("wind.steady must be a mapping {fx_n: N, fz_n: N}")
    w.steady_fx = num("wind.steady.fx_n", steady.get("fx_n", 0.0), -MAX_FORCE_N, MAX_FORCE_N)
    w.steady_fz = num("wind.steady.fz_n", steady.get("fz_n", 0.0), -MAX_FORCE_N, MAX_FORCE_N)
    gusts = data.get("gusts", [])
    if not isinstance(gusts, list):
        raise fail("wind.gusts must be a list of {t_s, duration_s, fx_n, fz_n}")
    for i, g in enumerate(gusts):
        where = f"wind.gusts[{i}]"
        keys = {"t_s", "duration_s", "fx_n", "fz_n"}
        if not isinstance(g, dict) or not {"t_s", "duration_s"} <= set(g) or set(g) - keys:
            raise fail(f"{where} must be {{t_s, duration_s, fx_n, fz_n}} (t_s and duration_s required)")
        w.gusts.append(
            Gust(
                num(f"{where}.t_s", g["t_s"], 0.0, 1e6),
                num(f"{where}.duration_s", g["duration_s"], 0.01, 600.0),
                num(f"{where}.fx_n", g.get("fx_n", 0.0), -MAX_FORCE_N, MAX_FORCE_N),
                num(f"{where}.fz_n", g.get("fz_n", 0.0), -MAX_FORCE_N, MAX_FORCE_N),
            )
        )
    if "random_gusts" in data:
        w.gusts += _random_gusts(data["random_gusts"], seed, num, fail)
    w.gusts.sort(key=lambda g: g.t_s)
    return w


def _random_gusts(r: object, seed: int, num: Num, fail: Callable[[str], Exception]) -> list[Gust]:
    """``{count, max_n, from_s, to_s, duration_s, vertical}``: ``count`` gusts starting uniformly
    in [from_s, to_s), horizontal peak uniform in [-max_n, max_n] (vertical too if ``vertical``
    is true), each lasting ``duration_s``; drawn from the seed on a stream of their own, so the
    sensor noise of the same seed does not change when gusts are added."""
    keys = {"count", "max_n", "from_s", "to_s", "duration_s", "vertical"}
    if not isinstance(r, dict) or not {"count", "max_n"} <= set(r) or set(r) - keys:
        raise fail("wind.random_gusts must be {count, max_n, from_s, to_s, duration_s, vertical}")
    count = r["count"]
    if not isinstance(count, int) or isinstance(count, bool) or not 0 <= count <= MAX_RANDOM_GUSTS:
        raise fail(f"wind.random_gusts.count must be an integer 0..{MAX_RANDOM_GUSTS}, got {count!r}")
    amp = num("wind.random_gusts.max_n", r["max_n"], 0.0, MAX_FORCE_N)
    t0 = num("wind.random_gusts.from_s", r.get("from_s", 0.0), 0.0, 1e6)
    t1 = num("wind.random_gusts.to_s", r.get("to_s", t0 + 60.0), t0, 1e6)
    dur = num("wind.random_gusts.duration_s", r.get("duration_s", 2.0), 0.01, 600.0)
    vertical = r.get("vertical", False)
    if not isinstance(vertical, bool):
        raise fail(f"wind.random_gusts.vertical must be true or false, got {vertical!r}")
    rng = np.random.default_rng([seed, 0x57494E44])  # "WIND": its own stream
    out = []
    for _ in range(count):
        t = float(rng.uniform(t0, t1)) if t1 > t0 else t0
        fx = float(rng.uniform(-amp, amp))
        fz = float(rng.uniform(-amp, amp)) if vertical else 0.0
        out.append(Gust(t, dur, fx, fz))
    return out
