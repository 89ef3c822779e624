"""The calibration bench of a simulated board: what a person does at a real bench (hang a mass
on each leg's lever, hold it at its mark with a peg, pull the peg), done through the board's
control channel. ``slopelander legs calibrate --bench sim:PATH`` finds it through the
``slopelander.benches`` entry point (docs/legs-build.md, "Calibration")."""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from slopelander.legs import LegBoard
from slopelander.legs.bench import CATCH_DEG, MARK_DEG
from slopelander_sitl.legboard.control import BoardControl
from slopelander_sitl.legboard.feeding import wait_for_driver


class SimBench:
    """The bench of a simulated board (``python -m slopelander_sitl.legboard``), through its control channel.

    On an external-clock board the bench is the board's clock: :meth:`wait` feeds it time, so
    a calibration runs as fast as the machine allows (no faster than the driver, ``driver``,
    hears it: :mod:`slopelander_sitl.legboard.feeding`); on a wall-clock board it sleeps."""

    STEP_S = 0.05

    def __init__(self, control_path: str | Path) -> None:
        self.ctl = BoardControl(control_path, timeout=30.0)
        state = self.ctl.state()
        self.external = state.get("clock") == "external"
        self.speed = float(state.get("speed", 1.0))
        self.now = float(state["time_s"])
        self._wall0 = time.monotonic()
        self._board0 = self.now
        self.driver: LegBoard | None = None  # the companion's driver: polled between steps

    def clock(self) -> float:
        if self.external:
            return self.now
        return self._board0 + (time.monotonic() - self._wall0) * self.speed

    def wait(self, seconds: float) -> None:
        end = self.clock() + seconds
        tick = 0.004 if self.external else 0.0  # the board's time moves in whole firmware ticks
        while self.clock() < end - tick + 1e-9:
            if self.external and self.driver is not None:
                wait_for_driver(self.driver, self.now)
                self.now = float(self.ctl.advance(min(end, self.now + self.STEP_S))["time_s"])
            else:
                time.sleep(min(self.STEP_S, (end - self.clock()) / self.speed))
            if self.driver is not None:
                self.driver.poll()

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
