"""The calibration bench of a simulated board: what a person does at a real bench (hang a mass
on each leg's lever, hold it at its mark with a peg, pull the peg), done through the board's
control channel. ``slopelander legs calibrate --bench sim:PATH`` finds it through the
``slopelander.benches`` entry point (docs/legs-build.md, "Calibration")."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

from slopelander.legs.bench import CATCH_DEG, MARK_DEG
from slopelander_sitl.legboard.control import BoardControl


class SimBench:
    """The bench of a simulated board (``python -m slopelander_sitl.legboard``), through its control channel.

    On an external-clock board the bench is the board's clock: :meth:`wait` feeds it time, so
    a calibration runs as fast as the machine allows; on a wall-clock board it sleeps. It feeds
    no time more than :data:`AHEAD_S` past what the driver has accounted for (``accounted``:
    :meth:`~slopelander.legs.driver.LegBoard.accounted_until`), as the lock-step echo does for a
    flight: a loaded machine's pseudo-terminal can hold the board's bytes for seconds."""

    STEP_S = 0.05
    #: board seconds the bench may run past the driver's accounted time (five of the 20 ms
    #: STATUS periods a calibration asks for; an acknowledgement's first timeout is 0.25 s)
    AHEAD_S = 0.1
    #: wall seconds one wait for the driver may last (a board really gone is then found silent)
    HOLD_MAX_S = 5.0

    def __init__(self, control_path: str | Path) -> None:
        self.ctl = BoardControl(control_path, timeout=30.0)
        state = self.ctl.state()
        self.external = state.get("clock") == "external"
        self.speed = float(state.get("speed", 1.0))
        self.now = float(state["time_s"])
        self._wall0 = time.monotonic()
        self._board0 = self.now
        self.poll: Callable[[], object] | None = None  # called between steps (the driver's poll)
        self.accounted: Callable[[], float | None] | None = None  # the driver's accounted time

    def clock(self) -> float:
        if self.external:
            return self.now
        return self._board0 + (time.monotonic() - self._wall0) * self.speed

    def wait(self, seconds: float) -> None:
        end = self.clock() + seconds
        tick = 0.004 if self.external else 0.0  # the board's time moves in whole firmware ticks
        while self.clock() < end - tick + 1e-9:
            if self.external:
                self._wait_for_driver()
                self.now = float(self.ctl.advance(min(end, self.now + self.STEP_S))["time_s"])
            else:
                time.sleep(min(self.STEP_S, (end - self.clock()) / self.speed))
            if self.poll is not None:
                self.poll()

    def _wait_for_driver(self) -> None:
        """Poll the driver until it has accounted for the board up to :data:`AHEAD_S` before now."""
        if self.accounted is None or self.poll is None:
            return
        give_up = time.monotonic() + self.HOLD_MAX_S
        while time.monotonic() < give_up:
            until = self.accounted()
            if until is None or self.now - until <= self.AHEAD_S:
                return
            self.poll()
            time.sleep(0.001)

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
