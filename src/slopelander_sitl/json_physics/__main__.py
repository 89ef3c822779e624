"""``python -m slopelander_sitl.json_physics``: serve slopelander's physics to ArduPilot SITL
(``arducopter --model JSON:127.0.0.1``) until SIGTERM or SIGINT."""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from slopelander_sitl.parent_watch import watch_parent


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m slopelander_sitl.json_physics", description=__doc__)
    ap.add_argument(
        "--port", type=int, default=9002, help="UDP port ArduPilot sends to (9002 + 10 x instance)"
    )
    ap.add_argument("--host", default="127.0.0.1", help="address to listen on (default loopback only)")
    ap.add_argument("--scenario", type=Path, default=None, help="scenario YAML (docs/simulated-vehicle.md)")
    ap.add_argument(
        "--legs",
        type=Path,
        default=None,
        metavar="CONTROL_SOCKET",
        help="the simulated leg board's control socket (python -m slopelander_sitl.legboard --control ...)",
    )
    ap.add_argument(
        "--events",
        type=Path,
        default=None,
        metavar="JSONL",
        help="append the measurement events (contact, outputs stopped, outputs reversed; "
        "slopelander_sitl.vehicle.events) and the body's true height over the surface every "
        "50 ms (TR_H) to this file, one JSON object a line, in ArduPilot's boot time",
    )
    ap.add_argument(
        "--rc-port",
        type=int,
        default=None,
        metavar="PORT",
        help="send the scenario's rc schedule to ArduPilot SITL's RC input on this UDP port of --host "
        "(5501 + 10 x instance); without it ArduPilot keeps its default sticks",
    )
    ap.add_argument(
        "--lockstep-port",
        type=int,
        default=None,
        metavar="PORT",
        help="hold ArduPilot while the companion is behind: its TIMESYNC echoes arrive on this UDP "
        "port of --host (src/slopelander_sitl/json_physics/companion_gate.py)",
    )
    ap.add_argument(
        "--real-time-below",
        type=float,
        default=None,
        metavar="M",
        help="with --lockstep-port: keep to real time while the vehicle is lower than this over the "
        "surface, whatever ArduPilot's speed-up (its script's thread keeps wall-clock steps)",
    )
    return ap.parse_args(argv)


def warm() -> None:
    """What every physics loads before its first frame, loaded once in a process that physics
    servers are forked from (:mod:`slopelander_sitl.warm`; the compiled model is the simulated vehicle's)."""
    import slopelander_sitl.json_physics.companion_gate
    import slopelander_sitl.json_physics.physics
    import slopelander_sitl.json_physics.pilot_rc
    import slopelander_sitl.json_physics.server
    import slopelander_sitl.legboard.control
    import slopelander_sitl.vehicle.legs_link
    import slopelander_sitl.vehicle.scenario  # noqa: F401


def main(argv: list[str] | None = None) -> int:
    a = parse_args(argv)

    def fail(msg: str) -> int:
        print(f"slopelander_sitl.json_physics: error: {msg}", file=sys.stderr)
        return 2

    if not 0 <= a.port <= 65535:
        return fail(f"--port {a.port} must lie within 0..65535")
    if a.rc_port is not None and not 1 <= a.rc_port <= 65535:
        return fail(f"--rc-port {a.rc_port} must lie within 1..65535")
    if a.lockstep_port is not None and not 1 <= a.lockstep_port <= 65535:
        return fail(f"--lockstep-port {a.lockstep_port} must lie within 1..65535")
    if a.real_time_below is not None and not (a.lockstep_port is not None and 0 < a.real_time_below < 1e3):
        return fail(
            f"--real-time-below {a.real_time_below:g} needs --lockstep-port and must lie within 0..1000 m"
        )

    from slopelander_sitl.json_physics.companion_gate import CompanionGate
    from slopelander_sitl.json_physics.physics import JsonPhysics
    from slopelander_sitl.json_physics.pilot_rc import PilotRc
    from slopelander_sitl.json_physics.server import JsonServer, ServerError
    from slopelander_sitl.vehicle.scenario import ScenarioError, load_scenario

    try:
        scenario = load_scenario(a.scenario)
    except ScenarioError as exc:
        return fail(str(exc))
    legs = None
    if a.legs is not None:
        from slopelander_sitl.legboard.control import ControlError
        from slopelander_sitl.vehicle.legs_link import LegsLink

        try:
            legs = LegsLink(a.legs)
        except ControlError as exc:
            return fail(f"leg board: {exc}")
    events = None
    if a.events is not None:
        try:
            events_file = open(a.events, "a", buffering=1)  # noqa: SIM115 - open while serving
        except OSError as exc:
            return fail(f"--events {a.events}: {exc.strerror}")

        def events(name: str, t: float, value: float) -> None:
            events_file.write(f'{{"name":"{name}","t":{t!r},"value":{value!r}}}\n')

    try:
        physics = JsonPhysics(scenario, legs, events)
        rc = PilotRc(scenario, a.rc_port, a.host) if a.rc_port is not None else None
        gate = None
        if a.lockstep_port is not None:
            try:
                gate = CompanionGate(a.lockstep_port, a.host, real_time_below_m=a.real_time_below)
            except OSError as exc:
                where = f"udp {a.host}:{a.lockstep_port}"
                raise ServerError(f"cannot listen on {where}: {exc.strerror}") from None
        server = JsonServer(physics, a.port, a.host, rc, gate)
    except ServerError as exc:
        if legs is not None:
            legs.close()
        return fail(str(exc))

    def stop(signum: int, frame: object) -> None:
        server.stop()

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    watch_parent()  # a launcher that dies takes its simulator with it
    print(
        f"json_physics ready udp={a.host}:{server.port} slope_deg={scenario.slope_deg} "
        f"start_on={scenario.start_on} legs={a.legs or 'none'}",
        flush=True,
    )
    try:
        server.serve_forever()
    finally:
        server.close()
        if rc is not None:
            rc.close()
        if legs is not None:
            legs.close()
        c = server.count
        held = ""
        if gate is not None:
            held = " " + gate.summary()
            gate.close()
        print(
            f"json_physics stopped frames={c.frames} repeats={c.repeats} missed={c.missed} "
            f"resets={c.resets} rejected={c.rejected}{held}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
