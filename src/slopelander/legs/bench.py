"""The calibration bench: what ``legs calibrate`` asks of the person (or simulator) beside it.

On the bench each leg carries a lever with a known mass; a peg holds the lever at its mark
while the board clamps, and is pulled to let the mass pull on the clamped joint
(docs/legs-build.md, "Calibration"). :class:`PromptBench` asks a person to do that;
:class:`SimBench` does it through a simulated board's control channel.
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


class SimBench:
    """The bench of a simulated board (``python -m sitl.legboard``), through its control channel.

    On an external-clock board the bench is the board's clock: :meth:`wait` feeds it time, so
    a calibration runs as fast as the machine allows; on a wall-clock board it sleeps."""

    STEP_S = 0.05

    def __init__(self, control_path: str | Path) -> None:
        try:
            from sitl.legboard.control import BoardControl
        except ImportError as exc:  # an install without the simulator
            raise RuntimeError(f"a simulated bench needs the sitl package of a checkout: {exc}") from None
        self.ctl = BoardControl(control_path, timeout=30.0)
        state = self.ctl.state()
        self.external = state.get("clock") == "external"
        self.speed = float(state.get("speed", 1.0))
        self.now = float(state["time_s"])
        self._wall0 = time.monotonic()
        self._board0 = self.now
        self.poll: Callable[[], object] | None = None  # called between steps (the driver's poll)

    def clock(self) -> float:
        if self.external:
            return self.now
        return self._board0 + (time.monotonic() - self._wall0) * self.speed

    def wait(self, seconds: float) -> None:
        end = self.clock() + seconds
        tick = 0.004 if self.external else 0.0  # the board's time moves in whole firmware ticks
        while self.clock() < end - tick + 1e-9:
            if self.external:
                self.now = float(self.ctl.advance(min(end, self.now + self.STEP_S))["time_s"])
            else:
                time.sleep(min(self.STEP_S, (end - self.clock()) / self.speed))
            if self.poll is not None:
                self.poll()

    def hang(self, load_nm: Sequence[float]) -> None:
        for leg, load in enumerate(load_nm):
            self.ctl.request(
                op="bench",
                leg=leg,
                load_nm=float(load),
                peg=True,
                spring=False,
                angle_deg=MARK_DEG,
                catch_deg=CATCH_DEG,
            )

    def hold(self, legs: Sequence[int]) -> None:
        for leg in legs:
            self.ctl.request(op="bench", leg=leg, peg=True, angle_deg=MARK_DEG)

    def release(self, legs: Sequence[int]) -> None:
        for leg in legs:
            self.ctl.request(op="bench", leg=leg, peg=False)

    def finish(self) -> None:
        for leg in range(4):
            self.ctl.request(op="bench", leg=leg, load_nm=0.0, peg=False, spring=True, catch_deg=0.0)
        self.ctl.close()
