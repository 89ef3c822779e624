"""``python -m slopelander_sitl.linkfault``: run the fault-injecting relay until interrupted."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading

from slopelander_sitl.linkfault.faults import FaultConfigError, LinkFaults
from slopelander_sitl.linkfault.relay import Relay


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m slopelander_sitl.linkfault",
        description="A MAVLink relay that drops, delays, duplicates, reorders and corrupts frames.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument(
        "--listen", required=True, help="where the companion connects: tcp:HOST:PORT or udp:HOST:PORT"
    )
    ap.add_argument("--to", required=True, help="the vehicle: tcp:HOST:PORT or udp:HOST:PORT")
    ap.add_argument("--control", type=int, default=0, help="UDP control port on 127.0.0.1 (0: any free)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the fault draws")
    for f, past in (
        ("drop", "dropped"),
        ("duplicate", "sent twice"),
        ("reorder", "held back"),
        ("corrupt", "corrupted"),
    ):
        ap.add_argument(f"--{f}", type=float, default=0.0, help=f"probability a frame is {past}")
    ap.add_argument("--delay", type=float, default=0.0, help="added delay per frame (s)")
    ap.add_argument("--jitter", type=float, default=0.0, help="extra random delay per frame, 0..this (s)")
    ap.add_argument(
        "--lockstep",
        action="store_true",
        help="the vehicle is a lock-stepped simulator: cuts last vehicle seconds, and during one the "
        "relay paces the vehicle in real time in the companion's place",
    )
    a = ap.parse_args(argv)
    try:
        faults = LinkFaults(a.drop, a.duplicate, a.reorder, a.corrupt, a.delay, a.jitter)
        relay = Relay(
            a.listen, a.to, faults, seed=a.seed, control_port=a.control, lockstep=a.lockstep
        ).start()
    except (FaultConfigError, OSError) as e:
        print(f"linkfault: {e}", file=sys.stderr)
        return 2
    print(f"linkfault ready port={relay.port} control={relay.control_port}", flush=True)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    with contextlib.suppress(KeyboardInterrupt):
        done.wait()
    relay.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
