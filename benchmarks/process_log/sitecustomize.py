"""Each Python process's CPU at its end, for ``benchmarks/suite_time.py --processes``.

Python imports ``sitecustomize`` at start-up from its path; suite_time puts this folder there
and names the log in ``SLOPELANDER_PROCESS_LOG``. Each process appends one JSON line when it
exits: its command line, user + system CPU and wall seconds. A process ended by SIGTERM with no
handler of its own gets one that writes the line and then ends by the signal, as without it (so
the run's processes are measured, not changed). Processes forked without exec (the simulators'
zygote children, a pool's workers) and non-Python ones (ArduCopter) write nothing.
"""

import atexit
import json
import os
import signal
import sys
import time

_LOG = os.environ.get("SLOPELANDER_PROCESS_LOG")
_T0 = time.monotonic()
_PID = os.getpid()


def _write(how: str) -> None:
    if os.getpid() != _PID:  # a forked child inherited the hook: not the process that started
        return
    t = os.times()
    line = {
        "argv": list(getattr(sys, "orig_argv", sys.argv))[1:6],
        "cpu_s": round(t.user + t.system, 3),
        "wall_s": round(time.monotonic() - _T0, 3),
        "end": how,
    }
    try:
        with open(_LOG, "a") as f:
            f.write(json.dumps(line) + "\n")
    except OSError:
        pass


def _on_term(signum, frame):
    _write("SIGTERM")
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGTERM)  # ended by the signal, as without this hook


if _LOG:
    atexit.register(_write, "exit")
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _on_term)
