"""How long the README's test command takes, and where the time goes.

Runs ``python3 -m pytest`` (the README's command, which ``.ci/run`` runs) with
SLOPELANDER_RECORD_DURATIONS set, prints the wall time, the load average before and after, the
summed test time (the two workers' share), the CPU time of the run with every process it
started and waited for (workers, simulated vehicles, ArduCopter, the leg boards: on 2 cores the
wall time cannot fall below half of it) and the longest work units; ``--write`` saves the
per-test times to tests/durations.json and their CPU (each test's process tree) to
tests/cpu_seconds.json, from which tests/conftest.py orders the work units it hands out.

This machine is shared: on 2026-11-27 the identification tests, their code unchanged, took 41 %
more CPU time at 07:30 than at 05:30, and a fixed piece of pure-Python work (the reference: the
interpreter's speed is what the simulated vehicles, the physics and the companions spend) took
0.74 s or 1.3-1.4 s depending on the minute. So the run is bracketed by that reference work,
timed before and after.

The reference brackets the run; the machine's speed also changes inside it. So a thread of this
(otherwise idle) process times a small fixed piece of the same work every ``--probe-every``
seconds of the run, on its own thread's CPU clock: the run prints how fast the machine was while
the tests ran and the CPU the run would have needed at the idle machine's speed (an estimate,
said as one). The probes are compared with probes timed the same way (each after a pause) on the
idle machine just before and after the run, not with the reference: a 25 ms probe after a pause
reads 1.3 times the same work inside the reference's 0.7 s even with nothing else running
(2026-11-27), so until then every run read about 1.3 times slower than the machine was.

A second thread reads the machine's busy cores from /proc/stat every second: the run prints
them per minute and the idle core-seconds at its start (the model's compile, one core) and end
(the last work units), where a 2-core run loses time that no test's CPU shows.

With ``--processes`` every Python process the run starts by exec logs its CPU when it ends
(benchmarks/process_log/sitecustomize.py) and the run sums it by command: the JSON physics, the
workers, the compile, pip, the command line.

    python3 benchmarks/suite_time.py [--write] [--processes] [-- extra pytest arguments]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


REFERENCE_LOOPS = 6_000_000
REFERENCE = (
    "import time\n"
    "t = time.process_time()\n"
    "x = 0\n"
    f"for i in range({REFERENCE_LOOPS}):\n"
    "    x = (x * 31 + i) % 1_000_003\n"
    "print(time.process_time() - t)\n"
)


def reference_s() -> float:
    """CPU seconds of the fixed reference work, in a fresh process (the best of three)."""
    return min(
        float(
            subprocess.run(
                [sys.executable, "-c", REFERENCE], capture_output=True, text=True, check=True
            ).stdout
        )
        for _ in range(3)
    )


PROBE_LOOPS = 200_000  # a thirtieth of the reference work: about 25 ms on the quiet machine
#: the reference's loop, as module-level code like the reference's (global names cost more)
PROBE = compile(
    f"x = 0\nfor i in range({PROBE_LOOPS}):\n    x = (x * 31 + i) % 1_000_003\n", "<probe>", "exec"
)


def probe_s() -> float:
    """Thread CPU seconds of a thirtieth of the reference work, in this process."""
    t = time.thread_time()
    exec(PROBE, {})
    return time.thread_time() - t


IDLE_PROBES = 8  # probes timed on the idle machine before and after the run
IDLE_PAUSE_S = 2.0  # s before each: a probe after a pause, as the run's are


def idle_probe_s(n: int = IDLE_PROBES, pause_s: float = IDLE_PAUSE_S) -> float:
    """The median of ``n`` probes, each after ``pause_s`` of nothing: the baseline of the run's."""
    samples = []
    for _ in range(n):
        time.sleep(pause_s)
        samples.append(probe_s())
    return statistics.median(samples)


class SpeedProbe(threading.Thread):
    """Times :func:`probe_s` every ``every_s`` wall seconds until stopped."""

    def __init__(self, every_s: float) -> None:
        super().__init__(daemon=True)
        self.every_s = every_s
        self.samples: list[float] = []
        self._halt = threading.Event()

    def run(self) -> None:
        while not self._halt.wait(self.every_s):
            self.samples.append(probe_s())

    def stop(self) -> list[float]:
        self._halt.set()
        self.join()
        return self.samples


class BusySampler(threading.Thread):
    """The machine's busy cores (all processes, from /proc/stat) every ``every_s`` seconds until
    stopped: where in the run cores stood idle (the model's compile before the workers start, the
    last units, tests that wait on the wall clock side by side). Nothing on a system without
    /proc/stat."""

    def __init__(self, every_s: float = 1.0) -> None:
        super().__init__(daemon=True)
        self.every_s = every_s
        self.samples: list[tuple[float, float]] = []  # (s since the start, cores busy)
        self._halt = threading.Event()

    @staticmethod
    def _read() -> tuple[int, int] | None:
        try:
            with open("/proc/stat") as f:
                ticks = [int(x) for x in f.readline().split()[1:]]
        except (OSError, ValueError):
            return None
        return ticks[3] + ticks[4], sum(ticks)  # idle + iowait, all

    def run(self) -> None:
        t0, last = time.monotonic(), self._read()
        while last is not None and not self._halt.wait(self.every_s):
            now = self._read()
            if now is None:
                return
            idle, total = now[0] - last[0], now[1] - last[1]
            if total > 0:
                busy = (os.cpu_count() or 1) * (1 - idle / total)
                self.samples.append((time.monotonic() - t0, busy))
            last = now

    def stop(self) -> list[tuple[float, float]]:
        self._halt.set()
        self.join()
        return self.samples


def busy_report(samples: list[tuple[float, float]], cores: int, tail_s: float = 120.0) -> list[str]:
    """Lines on the idle cores: per minute of the run, and in its first and last ``tail_s``."""
    if not samples:
        return []
    per_min: dict[int, list[float]] = defaultdict(list)
    for t, b in samples:
        per_min[int(t // 60)].append(b)
    end = samples[-1][0]
    # each sample stands for the interval since the one before it
    starts = [0.0] + [t for t, _ in samples[:-1]]
    spans = [(t, (cores - b) * (t - t0)) for t0, (t, b) in zip(starts, samples, strict=True)]
    idle = sum(s for _, s in spans)
    tail = sum(s for t, s in spans if t > end - tail_s)
    head = sum(s for t, s in spans if t <= tail_s)
    minutes = " ".join(f"{statistics.fmean(v):.2f}" for _, v in sorted(per_min.items()))
    return [
        f"cores busy, each minute: {minutes}",
        f"idle core-seconds: {idle:.0f} in all, {head:.0f} in the first {tail_s:.0f} s (the model's "
        f"compile is in it), {tail:.0f} in the last {tail_s:.0f} s",
    ]


def idle_minutes_report(
    samples: list[tuple[float, float]],
    spans: dict[str, list],
    t0_epoch: float,
    below: float = 1.7,
) -> list[str]:
    """For each minute whose cores were busy less than ``below`` on average: what each worker ran
    in it (the tests by the seconds they overlap the minute, longest first), so the idle cores
    can be put down to tests that wait on the wall clock, or to a worker with nothing left."""
    per_min: dict[int, list[float]] = defaultdict(list)
    for t, b in samples:
        per_min[int(t // 60)].append(b)
    out = []
    for minute, values in sorted(per_min.items()):
        busy = statistics.fmean(values)
        if busy >= below:
            continue
        lo, hi = t0_epoch + 60 * minute, t0_epoch + 60 * (minute + 1)
        by_worker: dict[str, list[tuple[float, str]]] = defaultdict(list)
        for nodeid, (worker, start, stop) in spans.items():
            overlap = min(hi, stop) - max(lo, start)
            if overlap > 0.5:
                by_worker[worker].append((overlap, nodeid.split("@")[0]))
        out.append(f"minute {minute} ({busy:.2f} cores busy):")
        for worker in sorted(by_worker):
            ran = sorted(by_worker[worker], reverse=True)
            busy_s = sum(o for o, _ in ran)
            tests = "; ".join(f"{o:.0f} s {name}" for o, name in ran[:3])
            more = f" and {len(ran) - 3} more" if len(ran) > 3 else ""
            out.append(f"  {worker}: {busy_s:.0f} s of tests: {tests}{more}")
    return out


def process_kind(argv: list[str]) -> str:
    """A process's command, short: ``-m module`` or the script, without its arguments."""
    if "-m" in argv[:-1]:
        return "-m " + argv[argv.index("-m") + 1]
    if "-c" in argv[:-1]:
        code = argv[argv.index("-c") + 1]
        return "-c " + code.replace("\n", " ")[:50]
    return " ".join(argv[:1])


def process_summary(log: Path) -> list[str]:
    """The logged processes' CPU summed by :func:`process_kind`, largest first."""
    if not log.exists():
        return ["no process wrote to the process log"]
    by: dict[str, list[float]] = defaultdict(lambda: [0, 0.0])
    torn = 0
    for line in log.read_text().splitlines():
        try:
            rec = json.loads(line)
        except ValueError:  # two processes' lines crossed in the file: counted, not read
            torn += 1
            continue
        row = by[process_kind(rec["argv"])]
        row[0] += 1
        row[1] += rec["cpu_s"]
    total = sum(cpu for _, cpu in by.values())
    out = [
        f"CPU of the Python processes started by exec, by command ({total / 60:.1f} min; the "
        "simulators forked from their zygotes and ArduCopter itself are not in it):"
    ]
    for kind, (n, cpu) in sorted(by.items(), key=lambda kv: -kv[1][1]):
        out.append(f"  {cpu:7.1f} s in {n:3.0f}  {kind}")
    if torn:
        out.append(f"  ({torn} unreadable lines left out)")
    return out


def unit_of(nodeid: str) -> str:
    return nodeid.split("::", 1)[0]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--write",
        action="store_true",
        help="save the times to tests/durations.json and the CPU to tests/cpu_seconds.json",
    )
    ap.add_argument("--top", type=int, default=15, help="how many of the longest modules to print")
    ap.add_argument("--probe-every", type=float, default=10.0, help="s between speed probes in the run")
    ap.add_argument(
        "--processes",
        action="store_true",
        help="log each Python process's CPU at its end (benchmarks/process_log) and sum it by command",
    )
    ap.add_argument("pytest_args", nargs="*", help="extra arguments for pytest (after --)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "durations.json"
        env = {**os.environ, "SLOPELANDER_RECORD_DURATIONS": str(out)}
        proc_log = Path(tmp) / "processes.jsonl"
        if a.processes:
            hook = str(REPO / "benchmarks" / "process_log")
            env["PYTHONPATH"] = os.pathsep.join(filter(None, [hook, env.get("PYTHONPATH")]))
            env["SLOPELANDER_PROCESS_LOG"] = str(proc_log)
        ref0 = reference_s()
        idle0 = idle_probe_s()
        load0 = os.getloadavg()
        cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        probe = SpeedProbe(a.probe_every)
        probe.start()
        busy = BusySampler()
        busy.start()
        t0, t0_epoch = time.monotonic(), time.time()
        run = subprocess.run([sys.executable, "-m", "pytest", "-q", *a.pytest_args], cwd=REPO, env=env)
        wall = time.monotonic() - t0
        probes = probe.stop()
        busy_samples = busy.stop()
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
        load1 = os.getloadavg()
        ref1 = reference_s()
        idle1 = idle_probe_s()
        if not out.exists():
            print("the run recorded no test times", file=sys.stderr)
            return 1
        seconds = json.loads(out.read_text())
        cpu_out = out.with_suffix(".cpu.json")
        test_cpu = json.loads(cpu_out.read_text()) if cpu_out.exists() else {}
        spans_out = out.with_suffix(".spans.json")
        spans = json.loads(spans_out.read_text()) if spans_out.exists() else {}
        if a.write:
            shutil.copy(out, REPO / "tests" / "durations.json")
            if cpu_out.exists():
                shutil.copy(cpu_out, REPO / "tests" / "cpu_seconds.json")
        processes = process_summary(proc_log) if a.processes else []
    per_module: dict[str, float] = defaultdict(float)
    for nodeid, s in seconds.items():
        per_module[unit_of(nodeid)] += s
    total = sum(seconds.values())
    print(
        f"\nwall {wall / 60:.1f} min, exit {run.returncode}; load {load0[0]:.1f} before, {load1[0]:.1f} after"
    )
    print(f"{len(seconds)} tests, {total / 60:.1f} min of test time ({total / wall:.2f} workers busy)")
    print(
        f"CPU time, every process the run waited for: {cpu / 60:.1f} min ({cpu / wall:.2f} cores busy on "
        f"average; on {os.cpu_count()} cores the run needs at least {cpu / os.cpu_count() / 60:.1f} min)"
    )
    ref = 0.5 * (ref0 + ref1)
    print(
        f"reference work: {ref0:.2f} s CPU before, {ref1:.2f} s after; the run's CPU is "
        f"{cpu / ref:.0f} reference works (compare runs by this, not by minutes)"
    )
    if probes:
        best = min(idle0, idle1)
        slow = sorted(p / best for p in probes)
        mean = statistics.fmean(slow)
        print(
            f"machine speed in the run ({len(slow)} probes, 1.00 = the idle machine's probe, "
            f"{idle0 * 1e3:.1f} ms before and {idle1 * 1e3:.1f} ms after the run): the probe "
            f"took {slow[0]:.2f}x / {statistics.median(slow):.2f}x / {slow[-1]:.2f}x (least / median / "
            f"most), {mean:.2f}x on average; at the idle machine's speed the run's CPU would be about "
            f"{cpu / mean / 60:.1f} min (an estimate: it assumes the tests slowed as the probe did)"
        )
    for line in busy_report(busy_samples, os.cpu_count() or 1):
        print(line)
    for line in idle_minutes_report(busy_samples, spans, t0_epoch):
        print(line)
    for line in processes[: a.top + 1]:
        print(line)
    for module, s in sorted(per_module.items(), key=lambda kv: -kv[1])[: a.top]:
        print(f"  {s:7.1f} s  {module}")
    if test_cpu:
        cpu_module: dict[str, float] = defaultdict(float)
        for nodeid, s in test_cpu.items():
            cpu_module[unit_of(nodeid)] += s
        print(f"CPU by module (each test's process tree: {sum(test_cpu.values()) / 60:.1f} min in all):")
        for module, s in sorted(cpu_module.items(), key=lambda kv: -kv[1])[: a.top]:
            print(f"  {s:7.1f} s  {module}")
        print("CPU by test:")
        for nodeid, s in sorted(test_cpu.items(), key=lambda kv: -kv[1])[: a.top]:
            print(f"  {s:7.1f} s  {nodeid.split('@')[0]}")
        # a test whose processes were busy less than one core for its wall time left a core to
        # the other worker, or to nobody: on 2 cores, the run's idle time is found here
        waits = {k: seconds[k] - c for k, c in test_cpu.items() if k in seconds}
        waited = sum(max(0.0, w) for w in waits.values()) / 60
        print(f"Waiting by test (wall time less CPU, {waited:.1f} min in all):")
        for nodeid, w in sorted(waits.items(), key=lambda kv: -kv[1])[: a.top]:
            print(f"  {w:7.1f} s  {nodeid.split('@')[0]} (wall {seconds[nodeid]:.1f} s)")
    return run.returncode


if __name__ == "__main__":
    sys.exit(main())
