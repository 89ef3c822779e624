"""How long the command line takes to answer: ``--help``, ``--version``, each subcommand's
``--help`` and an argument error of each, ``legs status`` against the simulated leg board, and a
second ``simulate`` (the model's compiled code already cached).

Each figure is the median wall time of several runs of a fresh process, printed beside the
median of ``python -c pass`` (the interpreter's own start) and their ratio, with the load average,
and the median CPU time (user + system) the process used: on a busy machine the wall time is
mostly waiting for a core, while the CPU time stays near what a quiet machine's wall time would
be. The runs keep Python's bytecode cache, as an installed package has it
(``PYTHONDONTWRITEBYTECODE`` is dropped for them: with it every module of this checkout is
compiled again in every process).
Goal (issue 23): under 0.5 s each, a second ``simulate`` under 1.5 s, on a quiet machine.

    python3 benchmarks/cli_latency.py [--runs 7] [--only simulate]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ENV = {
    **{k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"},
    "PYTHONPATH": os.pathsep.join([str(REPO / "src"), str(REPO)]),
}
CLI = [sys.executable, "-m", "slopelander.cli"]

CASES: list[tuple[str, list[str]]] = [
    ("--help", ["--help"]),
    ("--version", ["--version"]),
    ("simulate --help", ["simulate", "--help"]),
    ("map --help", ["map", "--help"]),
    ("fit --help", ["fit", "--help"]),
    ("demo --slope x", ["demo", "--slope", "x"]),
    ("land (no --connect)", ["land", "--legs-port", "/dev/null", "--slope", "35"]),
    (
        "land --slope 70",
        ["land", "--connect", "tcp:127.0.0.1:9", "--legs-port", "/dev/null", "--slope", "70"],
    ),
    (
        "land --connect garbage:foo",
        ["land", "--connect", "garbage:foo", "--legs-port", "/dev/null", "--slope", "35"],
    ),
    ("legs status (no --port)", ["legs", "status"]),
    ("simulate --slope x", ["simulate", "--slope", "x"]),
    ("lookup --speed x", ["lookup", "--slope", "35", "--speed", "x"]),
    ("params --out /proc/p.yaml", ["params", "--out", "/proc/p.yaml"]),
    ("map rvt --out /proc/maps", ["map", "rvt", "--out", "/proc/maps"]),
    ("table --out /proc/t.yaml", ["table", "--out", "/proc/t.yaml"]),
    ("synth --drops x", ["synth", "--out", "/tmp/x", "--drops", "x"]),
    ("compare (no dataset)", ["compare"]),
]


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def median_seconds(argv: list[str], runs: int, env: dict[str, str] = ENV) -> tuple[float, float]:
    """Median wall time and median CPU time (user + system) of ``runs`` fresh processes."""
    wall, cpu = [], []
    for _ in range(runs):
        t0, c0 = time.perf_counter(), _children_cpu()
        subprocess.run(argv, env=env, cwd=REPO, capture_output=True, timeout=300)
        wall.append(time.perf_counter() - t0)
        cpu.append(_children_cpu() - c0)
    return statistics.median(wall), statistics.median(cpu)


def legs_status_seconds(runs: int) -> tuple[float, float]:
    """``legs status`` against the simulated leg board on a pseudo-terminal (started once)."""
    with tempfile.TemporaryDirectory() as tmp:
        link = Path(tmp) / "legboard"
        board = subprocess.Popen(
            [sys.executable, "-m", "slopelander_sitl.legboard", "--link", str(link)],
            env=ENV,
            cwd=REPO,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            deadline = time.monotonic() + 30
            while not link.exists() and time.monotonic() < deadline:
                time.sleep(0.05)
            ok = subprocess.run(
                [*CLI, "legs", "status", "--legs-port", str(link)], env=ENV, capture_output=True
            )
            if ok.returncode != 0:
                raise SystemExit(f"legs status failed: {ok.stderr.decode()[-500:]}")
            return median_seconds([*CLI, "legs", "status", "--legs-port", str(link)], runs)
        finally:
            board.terminate()
            board.wait(10)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7, help="runs per figure (median)")
    ap.add_argument("--only", help="only the figures whose name holds this text (e.g. simulate)")
    args = ap.parse_args()
    subprocess.run([*CLI, "simulate"], env=ENV, cwd=REPO, capture_output=True)  # fill the caches
    base, base_cpu = median_seconds([sys.executable, "-c", "pass"], args.runs)
    print(f"{time.strftime('%Y-%m-%d %H:%M')}  load {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'python -c pass':32s} {base:6.3f} s  (baseline)  cpu {base_cpu:6.3f} s")
    cases = [(name, argv) for name, argv in CASES if args.only is None or args.only in name]
    rows = [(name, *median_seconds([*CLI, *argv], args.runs)) for name, argv in cases]
    if args.only is None or args.only in "legs status (simulated board)":
        rows.append(("legs status (simulated board)", *legs_status_seconds(args.runs)))
    if args.only is None or args.only in "simulate (second run)":
        rows.append(("simulate (second run)", *median_seconds([*CLI, "simulate"], args.runs)))
    for name, s, cpu in rows:
        goal = 1.5 if name.startswith("simulate (") else 0.5
        print(
            f"{name:32s} {s:6.3f} s  {s / base:4.1f}x baseline  {'ok' if s < goal else 'OVER'} (< {goal} s)"
            f"  cpu {cpu:6.3f} s"
        )
    print(f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
