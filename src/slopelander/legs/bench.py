"""The calibration bench: what ``legs calibrate`` asks of the person (or simulator) beside it.

On the bench each leg carries a lever with a known mass; a peg holds the lever at its mark
while the board clamps, and is pulled to let the mass pull on the clamped joint
(docs/legs-build.md, "Calibration"). :class:`PromptBench` asks a person to do that;
:func:`simulated_bench` finds the simulator's bench, which does it through a simulated
board's control channel.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol

G = 9.80665  # m/s²
MARK_DEG = 30.0  # the lever's mark: the leg's angle while the peg holds it
CATCH_DEG = 25.0  # a slipping lever is caught here (a stop on the bench, 5 deg below the mark)


class Bench(Protocol):
    """The bench's hands. Legs are the board's indices 0..3."""

    def clock(self) -> float:
        """Seconds, for the driver's timeouts (the board's time on a simulated bench)."""
        ...

    def wait(self, seconds: float) -> None:
        """Let ``seconds`` pass (feeding a simulated board that much time)."""
        ...

    def hang(self, load_nm: Sequence[float]) -> None:
        """Put each leg's lever load on (N·m at the joint), levers on their pegs at the mark,
        reset springs unhooked."""
        ...

    def hold(self, legs: Sequence[int]) -> None:
        """Lift these legs' levers back onto their pegs at the mark."""
        ...

    def release(self, legs: Sequence[int]) -> None:
        """Pull these legs' pegs: the mass now pulls on the clamped joint."""
        ...

    def finish(self) -> None:
        """Masses off, springs hooked again."""
        ...


class PromptBench:
    """A person at the bench, told what to do and asked to press Enter."""

    def __init__(self, ask: Callable[[str], str] = input, out: Callable[[str], None] = print) -> None:
        self._ask = ask
        self._out = out

    def clock(self) -> float:
        return time.monotonic()

    def wait(self, seconds: float) -> None:
        time.sleep(seconds)

    def hang(self, load_nm: Sequence[float]) -> None:
        loads = ", ".join(f"leg {i} {t:.3f} N·m" for i, t in enumerate(load_nm))
        self._ask(
            f"Hang the next mass on every lever ({loads}); reset springs unhooked; every lever "
            "on its peg at the mark. Enter when done: "
        )

    def hold(self, legs: Sequence[int]) -> None:
        self._ask(f"Lift the levers of legs {', '.join(map(str, legs))} back onto their pegs. Enter: ")

    def release(self, legs: Sequence[int]) -> None:
        self._ask(f"Pull the pegs of legs {', '.join(map(str, legs))} (levers free). Enter: ")

    def finish(self) -> None:
        self._out("Done: take the masses off and hook the reset springs again.")


BENCH_GROUP = "slopelander.benches"
"""Entry-point group of benches other packages provide: the simulator registers ``sim``
(a simulated board's bench, ``slopelander_sitl.legboard.bench``), so this package never
imports the simulator."""


def simulated_bench(control_path: str | Path) -> Bench:
    """The bench of a simulated board through its control channel (``--bench sim:PATH``)."""
    from importlib.metadata import entry_points

    found = entry_points(group=BENCH_GROUP, name="sim")
    if not found:
        raise RuntimeError(
            "a simulated bench needs slopelander's simulator (the slopelander_sitl package of a "
            "checkout, installed with it): pip install -e . in the checkout"
        )
    (ep,) = tuple(found)[:1]
    return ep.load()(control_path)
