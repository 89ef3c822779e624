"""``python -m slopelander_sitl.vehicle``: run the simulated ArduCopter until SIGTERM or SIGINT."""

from __future__ import annotations

import argparse
import math
import signal
import sys
from pathlib import Path

from slopelander_sitl.parent_watch import watch_parent

REPO = Path(__file__).resolve().parents[3]
DEFAULT_PARAMS = REPO / "firmware_params" / "sitl.parm"
DEFAULT_SCRIPT = REPO / "firmware_params" / "scripts" / "slopelander.lua"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m slopelander_sitl.vehicle", description=__doc__)
    ap.add_argument(
        "--endpoint",
        action="append",
        default=[],
        help="pymavlink connection string, repeatable (tcpin:127.0.0.1:5760, udpout:127.0.0.1:14550)",
    )
    ap.add_argument(
        "--params", type=Path, default=None, help=f"ArduPilot .parm file (default {DEFAULT_PARAMS})"
    )
    ap.add_argument(
        "--script", type=Path, default=None, help=f"on-board Lua script (default {DEFAULT_SCRIPT})"
    )
    ap.add_argument("--no-script", action="store_true", help="run without the on-board script")
    ap.add_argument("--scenario", type=Path, default=None, help="scenario YAML (docs/simulated-vehicle.md)")
    ap.add_argument(
        "--legboard-control", type=Path, default=None, help="simulated leg board's control socket"
    )
    ap.add_argument(
        "--legboard-period-ms",
        type=float,
        default=20.0,
        help="vehicle ms between exchanges with the leg board (default 20)",
    )
    ap.add_argument(
        "--speed", type=float, default=1.0, help="simulated seconds per wall second; 0 = as fast as possible"
    )
    ap.add_argument(
        "--lockstep", action="store_true", help="wait for a companion's TIMESYNC echo (50 ms lead)"
    )
    ap.add_argument(
        "--give-up",
        type=float,
        default=1.0,  # slopelander_sitl.vehicle.vehicle.LOCKSTEP_GIVE_UP_S
        help="lock-step: wall seconds without an echo before the vehicle runs free "
        "(default 1; longer on a loaded machine)",
    )
    ap.add_argument("--tlog", type=Path, default=None, help="write every message sent to this telemetry log")
    return ap.parse_args(argv)


def warm() -> None:
    """What every vehicle loads before its first tick (the imports, the compiled model from
    numba's cache), loaded once in the process vehicles are forked from (:mod:`slopelander_sitl.warm`)."""
    import slopelander_sitl.vehicle.legs_link
    import slopelander_sitl.vehicle.mavlink_endpoints
    import slopelander_sitl.vehicle.params
    import slopelander_sitl.vehicle.scripting
    import slopelander_sitl.vehicle.vehicle  # noqa: F401
    from slopelander_sitl.vehicle.scenario import load_scenario
    from slopelander_sitl.vehicle.world import start_on_ground

    start_on_ground(load_scenario(None))


def main(argv: list[str] | None = None) -> int:
    a = parse_args(argv)

    def fail(msg: str) -> int:
        print(f"slopelander_sitl.vehicle: error: {msg}", file=sys.stderr)
        return 2

    if a.speed < 0 or a.speed != a.speed:
        return fail(f"--speed {a.speed} must be >= 0")
    if not (a.give_up > 0 and math.isfinite(a.give_up)):
        return fail(f"--give-up {a.give_up} must be a positive number of seconds")
    params_path = a.params or DEFAULT_PARAMS
    if not params_path.is_file():
        return fail(f"parameter file {params_path} not found (give --params FILE)")
    script = None
    if not a.no_script:
        script = a.script or DEFAULT_SCRIPT
        if not script.is_file():
            return fail(f"on-board script {script} not found (give --script FILE or --no-script)")

    from slopelander_sitl.vehicle.mavlink_endpoints import EndpointError, Endpoints
    from slopelander_sitl.vehicle.params import ParamError, Params, load_parm
    from slopelander_sitl.vehicle.scenario import ScenarioError, load_scenario

    try:
        params = Params(load_parm(params_path))
        scenario = load_scenario(a.scenario)
    except (ParamError, ScenarioError) as exc:
        return fail(str(exc))
    sysid = params["MAV_SYSID"]
    if sysid != int(sysid) or not 1 <= sysid <= 255:
        return fail(f"{params_path}: MAV_SYSID {sysid:g} must be an integer 1..255")
    if not (a.legboard_period_ms > 0 and math.isfinite(a.legboard_period_ms)):
        return fail(f"--legboard-period-ms {a.legboard_period_ms} must be a positive number")
    legs = None
    if a.legboard_control is not None:
        from slopelander_sitl.legboard.control import ControlError
        from slopelander_sitl.vehicle.legs_link import LegsLink

        try:
            legs = LegsLink(a.legboard_control, period_s=a.legboard_period_ms / 1000.0)
        except ControlError as exc:
            return fail(f"leg board: {exc}")
    try:
        links = Endpoints(a.endpoint or ["tcpin:127.0.0.1:5760"], sysid=int(sysid), tlog=a.tlog)
    except EndpointError as exc:
        return fail(str(exc))

    from slopelander_sitl.vehicle.vehicle import Vehicle

    try:
        v = Vehicle(
            links,
            params,
            scenario,
            script=script,
            speed=a.speed,
            lockstep=a.lockstep,
            legs_link=legs,
            give_up_s=a.give_up,
        )
    except Exception as exc:
        links.close()
        return fail(f"cannot start: {type(exc).__name__}: {exc}")

    def stop(signum: int, frame: object) -> None:
        v.running = False

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    watch_parent()  # a launcher that dies takes its simulator with it
    print(
        f"vehicle ready endpoints={','.join(a.endpoint or ['tcpin:127.0.0.1:5760'])} speed={a.speed} "
        f"script={script or 'none'} slope_deg={scenario.slope_deg}",
        flush=True,
    )
    try:
        v.run()
    finally:
        links.close()
        if legs is not None:
            legs.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
