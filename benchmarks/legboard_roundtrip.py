"""Round trip companion → leg board → companion over the pseudo-terminal, firmware on MicroPython.

The companion's driver (``slopelander.legs.driver.LegBoard``) asks for a STATUS (``QUERY``) and
waits for it, and sends a command (``STOP`` on a loose leg) and waits for its ACK, ``--n`` times
each; the board is ``python -m slopelander_sitl.legboard`` on the external clock (fed no time, so nothing
but the answers crosses the link). The same run measures the firmware on this CPython as the
peer. Prints median, 90th and 99th percentile and maximum in ms.

    SLOPELANDER_MICROPYTHON=/path/to/micropython python3 benchmarks/legboard_roundtrip.py --n 500
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]

from slopelander.legs import LegBoard, messages  # noqa: E402


def _board(runtime: str, directory: Path) -> tuple[subprocess.Popen, Path]:
    link = directory / f"legs-{runtime}"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "src"), str(ROOT)]))
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "slopelander_sitl.legboard",
            "--link",
            str(link),
            "--clock",
            "external",
            "--runtime",
            runtime,
        ],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    line = proc.stdout.readline()
    if "legboard ready" not in line:
        proc.kill()
        raise SystemExit(f"board on {runtime} did not start: {line!r}")
    return proc, link


def measure(runtime: str, n: int, directory: Path) -> dict[str, list[float]]:
    proc, link = _board(runtime, directory)
    out: dict[str, list[float]] = {"QUERY→STATUS": [], "STOP→ACK": []}
    try:
        with LegBoard.open(str(link), timeout=5.0, silence_timeout=60.0) as drv:
            drv.query(timeout=5.0)
            for _ in range(n):
                t0 = time.perf_counter()
                drv.query(timeout=5.0)
                out["QUERY→STATUS"].append(time.perf_counter() - t0)
            for _ in range(n):
                t0 = time.perf_counter()
                op = drv.start_stop([0], timeout=5.0)
                drv.poll()
                while not op.acked and op.exception() is None:
                    drv._wait_readable(0.01)
                    drv.poll()
                out["STOP→ACK"].append(time.perf_counter() - t0)
                assert op.exception() is None, op.exception()
    finally:
        proc.terminate()
        proc.wait(10)
    return out


def _row(name: str, xs: list[float]) -> str:
    ms = sorted(x * 1000 for x in xs)
    q = statistics.quantiles(ms, n=100)
    median = statistics.median(ms)
    return f"  {name:<13} median {median:6.3f}  p90 {q[89]:6.3f}  p99 {q[98]:6.3f}  max {ms[-1]:7.3f} ms"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=300)
    a = ap.parse_args()
    if not os.environ.get("SLOPELANDER_MICROPYTHON"):
        raise SystemExit("set SLOPELANDER_MICROPYTHON to a MicroPython unix-port binary")
    with tempfile.TemporaryDirectory(prefix="rt-") as d:
        results = {rt: measure(rt, a.n, Path(d)) for rt in ("micropython", "cpython")}
    print(
        f"leg-board round trip over a pty, {a.n} each, protocol {messages.PROTOCOL_VERSION}, "
        f"load average {os.getloadavg()[0]:.1f}"
    )
    for rt, res in results.items():
        print(f"firmware on {rt}:")
        for name, xs in res.items():
            print(_row(name, xs))


if __name__ == "__main__":
    main()
