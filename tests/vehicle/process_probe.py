"""Run by tests/vehicle/test_processes.py as ``python -m tests.vehicle.process_probe``: prints what
it was given (arguments, working directory, environment, its process ids, its network interfaces,
the command line of the process it is: a fork of the forkserver keeps the forkserver's, and
whether the simulators' modules were loaded before it ran), says one line on stderr, then sleeps
(argument ``sleep``), or starts the probe again through ``slopelander_sitl.processes.start`` and prints what
that one said and its exit status (argument ``start``), or exits with the status its first
argument names."""

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

if __name__ == "__main__":
    said = {
        "argv": sys.argv[1:],
        "cwd": os.getcwd(),
        "env": os.environ.get("PROBE_VALUE"),
        "pid": os.getpid(),
        "ppid": os.getppid(),
        "interfaces": sorted(name for _, name in socket.if_nameindex()),
        "cmdline": Path("/proc/self/cmdline").read_text().split("\0"),
        "warm": "slopelander_sitl.warm" in sys.modules and "slopelander_sitl.vehicle.vehicle" in sys.modules,
    }
    if sys.argv[1:2] == ["start"]:
        from slopelander_sitl import processes
        from slopelander_sitl.vehicle.launch import child_env

        p = processes.start(
            "tests.vehicle.process_probe",
            ["5"],
            env=child_env(),
            cwd=os.getcwd(),
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
        )
        out, _ = p.communicate(timeout=30)
        said["child"] = json.loads(out)
        said["child_status"] = p.returncode
    print(json.dumps(said), flush=True)
    print("to stderr", file=sys.stderr, flush=True)
    if "sleep" in sys.argv:
        time.sleep(600)
    sys.exit(int(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].isdigit() else 0)
