"""Run by tests/vehicle/test_zygote.py as ``python -m tests.vehicle.zygote_probe``: prints what it
was given (arguments, working directory, environment, its process ids), says one line on stderr,
then sleeps (argument ``sleep``) or exits with the status its first argument names."""

import json
import os
import sys
import time

if __name__ == "__main__":
    said = {
        "argv": sys.argv[1:],
        "cwd": os.getcwd(),
        "env": os.environ.get("PROBE_VALUE"),
        "pid": os.getpid(),
        "ppid": os.getppid(),
    }
    print(json.dumps(said), flush=True)
    print("to stderr", file=sys.stderr, flush=True)
    if "sleep" in sys.argv:
        time.sleep(600)
    sys.exit(int(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].isdigit() else 0)
