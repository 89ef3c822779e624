"""``slopelander simulate``: one landing of the planar model, its outcome and a picture."""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING

from slopelander.commands.options import renamed
from slopelander.errors import SlopelanderError
from slopelander.outputs import check_output

if TYPE_CHECKING:
    from slopelander.model import Model, Trajectory

# ``LandingConditions()``'s defaults, written out so that ``--help`` and argument errors answer
# without importing the model (numba); tests/cli/test_cli_latency.py keeps them equal.
_D = SimpleNamespace(
    slope_deg=0.0,
    speed=2.0,
    horizontal_speed=0.0,
    pitch_deg=0.0,
    pitch_rate_dps=0.0,
    tau_up=1.7,
    tau_down=1.7,
    angle_up_deg=37.5,
    angle_down_deg=37.5,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "simulate",
        help="simulate one landing with the planar model",
        description="Simulate one landing with the planar model and print its outcome. Exit codes: "
        "0 simulated (whatever the outcome), 1 an error, 2 a usage error.",
    )
    p.add_argument("--slope", type=float, default=_D.slope_deg, help="surface slope, deg")
    p.add_argument("--speed", type=float, default=_D.speed, help="vertical impact speed, m/s")
    p.add_argument(
        "--horizontal-speed",
        type=float,
        default=_D.horizontal_speed,
        help="horizontal speed at impact, m/s (+ = downhill)",
    )
    p.add_argument("--pitch", type=float, default=_D.pitch_deg, help="pitch at impact, deg")
    p.add_argument("--pitch-rate", type=float, default=_D.pitch_rate_dps, help="pitch rate, deg/s")
    p.add_argument("--tau-up", type=float, default=_D.tau_up, help="uphill joint friction, N*m")
    p.add_argument("--tau-down", type=float, default=_D.tau_down, help="downhill joint friction, N*m")
    p.add_argument("--angle-up", type=float, default=_D.angle_up_deg, help="uphill leg angle, deg")
    p.add_argument("--angle-down", type=float, default=_D.angle_down_deg, help="downhill leg angle, deg")
    p.add_argument("--reverse", action="store_true", help="100 %% reverse thrust commanded at impact")
    p.add_argument(
        "--reverse-percent",
        type=float,
        default=None,
        help="reverse rotor command, percent of full: a speed, thrust goes with its square "
        "(implies --reverse)",
    )
    p.add_argument("--reverse-delay", type=float, default=0.0, help="seconds from impact to the command")
    p.add_argument(
        "--reverse-duration",
        type=float,
        default=math.inf,
        help="seconds the reverse thrust is held from its command, then ended (default: held to the "
        "end; the landing is judged after the thrust)",
    )
    p.add_argument(
        "--reverse-ramp",
        type=float,
        default=0.0,
        help="seconds over which it then ramps to zero (default 0: a step)",
    )
    p.add_argument("--rigid", action="store_true", help="stock rigid landing gear instead of FSA legs")
    p.add_argument("--params", type=Path, help="model parameter file (YAML)")
    p.add_argument("--without", nargs="+", default=[], metavar="EFFECT", help="switch effects off")
    p.add_argument("--effects-file", type=Path, help="Python file with user effects to add")
    p.add_argument("--dt", type=float, default=None, help="integration step, s")
    p.add_argument("--plot", type=Path, help="write a PNG of the landing here")
    p.add_argument("--csv", type=Path, help="write the 200 Hz trajectory here")
    for old in ("", "-percent", "-delay", "-duration", "-ramp"):
        renamed(p, f"--rvt{old}", f"--reverse{old}")
    # its files are closed when run returns: the process may end without the interpreter's teardown
    p.set_defaults(handler=run, exit_without_teardown=True)


def build_model(args: argparse.Namespace) -> Model:
    from slopelander.model import Model, load_effects

    model = Model.from_file(str(args.params)) if args.params else Model.default()
    if args.rigid:
        model = model.rigid()
    if args.without:
        model = model.without(*args.without)
    if args.effects_file:
        for effect in load_effects(args.effects_file):
            model = model.with_user_effect(effect)
    return model


def run(args: argparse.Namespace) -> int:
    check_output(args.plot, "--plot")
    check_output(args.csv, "--csv")
    from slopelander.model import LandingConditions, simulate
    from slopelander.model.conditions import reverse_text

    pct = args.reverse_percent if args.reverse_percent is not None else (100.0 if args.reverse else 0.0)
    if pct > 0 and "rotors" in args.without:
        raise SlopelanderError(
            "reverse thrust needs the rotors: drop --reverse/--reverse-percent or 'rotors' from --without"
        )
    cond = LandingConditions(
        slope_deg=args.slope,
        speed=args.speed,
        horizontal_speed=args.horizontal_speed,
        pitch_deg=args.pitch,
        pitch_rate_dps=args.pitch_rate,
        tau_up=args.tau_up,
        tau_down=args.tau_down,
        angle_up_deg=args.angle_up,
        angle_down_deg=args.angle_down,
        reverse_percent=pct,
        reverse_delay=args.reverse_delay,
        reverse_duration=args.reverse_duration,
        reverse_ramp=args.reverse_ramp,
    )
    model = build_model(args)
    tr = simulate(cond, model, dt=args.dt)
    if model.rigid_gear:
        gear = f"rigid gear (legs locked at {cond.angle_up_deg:g}/{cond.angle_down_deg:g} deg)"
    else:
        gear = f"FSA legs, tau up/down {cond.tau_up:g}/{cond.tau_down:g} N*m"
    end = ""
    if cond.thrust_ends:
        ramp = f"ramped to zero over {cond.reverse_ramp:g} s" if cond.reverse_ramp else "then stopped"
        end = f" held {cond.reverse_duration:g} s, {ramp}"
    print(f"landing: {cond.slope_deg:g} deg slope, {cond.speed:g} m/s, {gear}, {reverse_text(pct)}{end}")
    print(tr.summary())
    if args.plot:
        from slopelander.plots.landing import plot_landing

        print(f"plot: {plot_landing(tr, args.plot)}")
    if args.csv:
        print(f"trajectory: {write_csv(tr, args.csv)}")
    return 0


CSV_HEADER = ["t_s", "x_m", "z_m", "pitch_rad", "x_rate_m_s", "z_rate_m_s", "pitch_rate_rad_s"]


def write_csv(tr: Trajectory, path: Path) -> Path:
    """The sampled trajectory in the drop-recording column order, SI units named in the header
    (pitch in radians, x downhill, z up)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_HEADER)
        for t, row in zip(tr.t, tr.states, strict=True):
            w.writerow([f"{t:.4f}", *(f"{v:.6f}" for v in row)])
    return path
