"""CPU time of a process and everything it started (Linux /proc): how the test suite's timing
and the benchmarks charge a test or a start with the simulators, ArduCopters and leg boards it ran.
"""

from __future__ import annotations

import os


def process_tree_cpu(root: int | None = None) -> float:
    """CPU seconds of process ``root`` (this one by default) and every process under it, however
    deep, the ones that ended and were waited for included (their time is in their parent's
    cutime and cstime)."""
    root = os.getpid() if root is None else root
    tick = os.sysconf("SC_CLK_TCK")
    parent: dict[int, int] = {}
    cpu: dict[int, float] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                st = f.read()
        except OSError:  # ended while the folder was read
            continue
        fields = st[st.rfind(")") + 2 :].split()
        parent[int(d)] = int(fields[1])
        cpu[int(d)] = sum(int(x) for x in fields[11:15]) / tick  # utime, stime, cutime, cstime

    def under(pid: int) -> bool:
        while pid > 1:
            if pid == root:
                return True
            pid = parent.get(pid, 0)
        return False

    return sum(c for pid, c in cpu.items() if under(pid))
