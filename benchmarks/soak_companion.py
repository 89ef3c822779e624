"""The companion as a process of its own, for the soak's ``companion_kill`` fault: one landing
session (:class:`slopelander.controller.session.Session`, as ``slopelander land`` flies it) on the
vehicle's link and the leg board's pseudo-terminal, each transition printed as a JSON line as it
happens. The soak kills this process (SIGKILL: no handler runs, no last command is sent) in a
drawn state and watches what the vehicle does with nobody on its companion port.

    python3 benchmarks/soak_companion.py --url tcp:127.0.0.1:PORT --legs /dev/pts/N --slope 35 \
        --preset 1.7 2.3 --angle-up 25 --cut 0.55
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from slopelander.controller.session import Session, SessionError  # noqa: E402
from slopelander.legs.calibration import load_calibration  # noqa: E402
from slopelander_sitl.rig import RIG_RATES, config  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--url", required=True, help="the vehicle's MAVLink (the companion's port)")
    ap.add_argument("--legs", required=True, help="the leg board's serial port (a pty)")
    ap.add_argument("--slope", type=float, required=True, help="deg")
    ap.add_argument("--preset", type=float, nargs=2, required=True, metavar=("UP", "DOWN"), help="N*m")
    ap.add_argument("--angle-up", type=float, default=None, help="uphill legs' angle (deg)")
    ap.add_argument("--cut", type=float, required=True, help="reflex.cut_height_m")
    ap.add_argument("--timeout", type=float, default=120.0, help="local s")
    a = ap.parse_args()
    if not all(math.isfinite(v) for v in (a.slope, a.cut, *a.preset)):
        ap.error("--slope, --preset and --cut must be finite numbers")
    cfg = config(link=dict(RIG_RATES), reflex={"cut_height_m": a.cut})
    try:
        with Session(a.url, cfg, calibration=load_calibration(), telemetry=False, lockstep=True) as s:
            s.connect(timeout_s=30.0)
            s.open_legs(a.legs)
            print(json.dumps({"connected": True}), flush=True)
            lander = s.make_lander(
                tuple(a.preset), slope_deg=a.slope, uphill_angle_deg=a.angle_up, record=sys.stdout
            )
            end = lander.run(a.timeout)
            print(json.dumps({"end": end}), flush=True)
    except SessionError as exc:
        print(json.dumps({"error": str(exc)}), flush=True)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
