"""Survey passes on real ArduCopter SITL beside busy processes: how many lose the link.

The load flake of the test suite, measured on its own: one vehicle takes off over the 35 deg
roof and flies survey passes (``slopelander land``'s slope measurement, the leg board polled as a
landing polls it) while ``--busy`` processes spin on the machine's cores, until the link is
lost or ``--passes`` are flown (after a loss ArduCopter's failsafes own the vehicle). Prints
each pass, then how many were flown and whether the last lost the link, the leg board's
silences (the rig reopens the board after one) and the slowest leg-board poll (the companion's
loop waits that long).

    SLOPELANDER_ARDUCOPTER=/path/to/arducopter python3 benchmarks/survey_under_load.py --passes 40

Run it on two checkouts to compare them, one after the other in one sitting (the machine's
speed moves with its hours): ``PYTHONPATH=OTHER/src python3 benchmarks/survey_under_load.py``.
Records: ``benchmarks/results/``.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import time


def spin(until: float) -> None:
    while time.monotonic() < until:
        pass


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--passes", type=int, default=40)
    ap.add_argument("--busy", type=int, default=2, help="busy processes beside it (default 2)")
    ap.add_argument("--seed", type=int, default=42)
    a = ap.parse_args(argv)
    import slopelander_sitl
    from slopelander.controller.slope_estimate import SurfaceTrack
    from slopelander.controller.survey import measure_slope
    from slopelander.legs.errors import LegBoardError
    from slopelander_sitl.rig import Rig, config

    print(f"simulator from {os.path.dirname(slopelander_sitl.__file__)}; load {os.getloadavg()}")
    busy = [
        multiprocessing.Process(target=spin, args=(time.monotonic() + 3600,), daemon=True)
        for _ in range(a.busy)
    ]
    for p in busy:
        p.start()
    lost, silences, slowest, flown = [], 0, 0.0, 0
    rig = Rig(slope_deg=35, autopilot="ardupilot", seed=a.seed)

    def poll() -> None:
        nonlocal silences, slowest
        rig.link.poll()
        if rig.link.lost and not lost:
            lost.append(rig.link.lost_why)
        t0 = time.monotonic()
        try:
            rig.legs.poll()
        except LegBoardError as exc:
            silences += 1
            print(f"  leg board: {exc}; reopened", flush=True)
            rig.open_legs()
        slowest = max(slowest, time.monotonic() - t0)
        rig.read_events()

    try:
        rig.take_off(2)
        cfg = config()
        t0 = time.monotonic()
        for i in range(a.passes):
            track = SurfaceTrack(cfg["slope.pair_window_s"])
            rig.link.add_listener(track.feed)
            try:
                rig.go_over_roof(2)
                est, _ = measure_slope(rig.link, cfg, track, tick=poll, note=lambda _: None)
                print(f"pass {i}: {est.describe()}", flush=True)
            except Exception as exc:  # a pass that fails is the figure: say why, then stop
                print(f"pass {i}: failed ({type(exc).__name__}: {exc}); link: {rig.link.lost_why}")
                break
            finally:  # a checkout before Link.remove_listener: its list
                remove = getattr(rig.link, "remove_listener", rig.link._listeners.remove)
                remove(track.feed)
            flown += 1
            if rig.link.lost and not lost:  # lost in the transit (the rig's own polls)
                lost.append(rig.link.lost_why)
            if lost:
                break
        took = time.monotonic() - t0
    finally:
        for p in busy:
            p.terminate()
        rig.close()
    ended = f"the link lost in the last ({lost[0]})" if lost else "the link never lost"
    print(
        f"{flown} of {a.passes} passes flown, {ended}; leg board silent {silences} times; "
        f"slowest leg-board poll {slowest * 1000:.0f} ms; {took:.0f} s beside {a.busy} busy processes"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
