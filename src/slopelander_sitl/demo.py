"""``slopelander demo``: a whole simulated flight and landing on a roof, no hardware.

The simulated leg board and the simulated ArduCopter (running the real on-board Lua script), or
real ArduCopter SITL behind the same physics, run as their own processes (:class:`slopelander_sitl.rig.Rig`);
the companion flies them through the same landing session ``slopelander land`` flies a real
vehicle with (:class:`slopelander.controller.session.Session`): the same streams, survey, plan,
leg board and landing controller. The demo adds only what a pilot would do by hand: take off from a
level pad, fly over the roof, and after the landing take off again. Everything it saw is written
out: the MAVLink telemetry log (``flight.tlog``), the state transitions (``transitions.jsonl``),
the slope estimate, the outcome (``result.json``) and a picture of the flight (``flight.png``); on
real ArduCopter also its own DataFlash log (``flight.bin``: ``slopelander compare`` reads it).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from slopelander.errors import SlopelanderError
from slopelander.model.conditions import reverse_text

CRUISE_HEIGHT_M = 3.0  # take-off height above the pad
APPROACH_RANGE_M = 2.0  # the height above the roof the landing starts from (within the 3 m range)


class DemoError(SlopelanderError):
    """The demo could not start or did not finish its flight."""


@dataclass
class DemoResult:
    """What a person wants to know after the flight."""

    outcome: str  # LANDED_AND_RESET, LANDED, or the state the companion stopped in
    slope_deg: float
    preset_nm: tuple[float, float]
    preset_source: str
    uphill_angle_deg: float | None  # the preset's (the table's), set on the board before the descent
    uphill_angle_measured_deg: float | None  # as the board reported it just before the cut
    expected_impact_mps: float
    cut_height_m: float  # the landing's: the configured one, raised where the uphill foot touches above it
    impact_mps: float | None
    slide_m: float | None
    min_pitch_deg: float | None
    reflex_states: list[int]
    transitions: list[dict]
    files: dict[str, str]
    wall_s: float

    def summary(self) -> str:
        lines = [
            f"demo: {self.slope_deg:g} deg roof, legs {self.preset_nm[0]:.2f}/{self.preset_nm[1]:.2f} N*m "
            f"({self.preset_source}), expected impact {self.expected_impact_mps:.2f} m/s",
        ]
        if self.uphill_angle_deg is not None:
            measured = self.uphill_angle_measured_deg
            lines.append(
                f"uphill legs: preset {self.uphill_angle_deg:.1f} deg, board reported "
                + ("nothing" if measured is None else f"{measured:.1f} deg")
                + " before the cut"
            )
        for h in self.transitions:
            lines.append(f"  {h['t']:8.2f} s  {h['from'] or '-':>9} -> {h['to']:<9} {h['reason']}")
        if self.impact_mps is not None:
            lines.append(
                f"impact {self.impact_mps:.2f} m/s down; moved {self.slide_m:.2f} m downhill after it; "
                f"lowest pitch {self.min_pitch_deg:.0f} deg"
            )
        lines.append(f"outcome: {self.outcome}  ({self.wall_s:.0f} s wall)")
        lines += [f"{k}: {v}" for k, v in self.files.items()]
        return "\n".join(lines)


def check_out_dir(out: Path) -> None:
    """Refuse an output folder that cannot be written before any process starts."""
    if out.exists() and not out.is_dir():
        raise DemoError(f"--out {out} is a file; give a folder")
    parent = out if out.exists() else out.parent
    if not parent.exists():
        raise DemoError(f"--out {out}: folder {parent} does not exist (create it first)")
    if not os.access(parent, os.W_OK):
        raise DemoError(f"--out {out}: folder {parent} is not writable")


def run_demo(
    out: Path = Path("slopelander-demo"),
    slope_deg: float = 35.0,
    speed: float = 2.0,
    table: Path | None = None,
    plot: bool = True,
    echo=print,
    autopilot: str = "sim",
    arducopter: str | Path | None = None,
) -> DemoResult:
    """Fly the whole demo; ``speed`` is simulated seconds per wall second. ``autopilot`` is
    ``"sim"`` (the project's simulated ArduCopter) or ``"ardupilot"``: real ArduCopter SITL
    (``arducopter``, else ``$SLOPELANDER_ARDUCOPTER``) behind the same physics, in a loopback-only
    network namespace; ``speed`` is then its ``--speedup`` (it runs in lock-step with the physics,
    so a busy machine only slows it)."""
    from slopelander.controller.table import LookupTable
    from slopelander.controller.telemetry import landing_figures, uphill_angle_before_cut
    from slopelander_sitl.rig import OVER_ROOF_X_M, Rig, RigError

    if not (math.isfinite(slope_deg) and 0.0 <= slope_deg <= 60.0):
        raise DemoError(f"--slope must lie within 0..60 deg, got {slope_deg:g}")
    if not (math.isfinite(speed) and 0.1 <= speed <= 20.0):
        raise DemoError(f"--speed must lie within 0.1..20, got {speed:g}")
    if autopilot not in ("sim", "ardupilot"):
        raise DemoError(f"--autopilot must be sim or ardupilot, not {autopilot!r}")
    binary = None
    if autopilot == "ardupilot":
        from slopelander_sitl.ardupilot import arducopter_binary
        from slopelander_sitl.launching import LaunchError

        try:
            binary = arducopter_binary(arducopter)
        except LaunchError as exc:
            raise DemoError(str(exc)) from None
    check_out_dir(out)
    out.mkdir(exist_ok=True)
    for name in ("transitions.jsonl", "slope_estimate.json", "result.json", "flight.bin"):
        (out / name).unlink(missing_ok=True)  # a folder flown before holds only this flight's files
    files = {"telemetry log": str(out / "flight.tlog"), "transitions": str(out / "transitions.jsonl")}
    wall0 = time.monotonic()
    what = "real ArduCopter SITL" if autopilot == "ardupilot" else "the simulated vehicle"
    echo(
        f"starting the simulated leg board and {what} ({speed:g}x real time at most; the first run "
        "after an install compiles the model) ..."
    )
    slope_drawn = None
    try:
        rig = Rig(
            slope_deg,
            speed=speed,
            scenario={"start_on": "pad"},
            autopilot=autopilot,
            arducopter=binary,
            arducopter_speedup=speed,
            out=out,
        )
    except RigError as exc:
        raise DemoError(str(exc)) from None
    session = rig.session
    try:
        if table is not None:
            session.table = LookupTable.load(table)
        cfg = session.cfg
        preset, expected = session.plan(slope_deg, pilot_switch=False)
        up, down = preset.tau_up, preset.tau_down
        echo(f"autopilot: {rig.info.describe()}")
        echo(f"take-off from the pad to {CRUISE_HEIGHT_M:g} m, then over the {slope_deg:g} deg roof")
        try:
            # ArduCopter arms in GUIDED once its EKF has an origin (20-40 s of vehicle time)
            rig.take_off(CRUISE_HEIGHT_M)
            rig.go_over_roof(height_m=APPROACH_RANGE_M, x=OVER_ROOF_X_M)
        except RigError as exc:
            raise DemoError(str(exc)) from None
        # the slope measured as `slopelander land` does (a survey pass when the approach saw too
        # little), for the picture and slope_estimate.json; the landing uses the demo's slope,
        # checked against a measured one in CHECKS, and the take-off leaves the measured plane
        survey_t0 = rig.now
        choice = session.measure_slope("auto", tick=rig.poll, wall_s=120 / speed + 60)
        slope_drawn = {
            "record": choice.estimate.record(),
            "survey": (survey_t0, survey_t0 + choice.survey_s) if choice.survey_s else None,
            "true_slope_deg": float(slope_deg),
        }
        files["slope estimate"] = str(out / "slope_estimate.json")
        cut_m = session.landing_config(cfg, slope_deg, preset.angle_up_deg, say=False)["reflex.cut_height_m"]
        echo(
            f"landing: legs {up:.2f}/{down:.2f} N*m from the {preset.source}, descent "
            f"{cfg['descent.rate_mps']:g} m/s, motors stopped at {cut_m:.2f} m, "
            f"{reverse_text(cfg['reflex.reverse_thrust_pct'])}"
        )
        # a measurement the estimator refused (a survey cut short on a loaded machine) is shown and
        # recorded, and the demo lands on its own roof's slope, as it always knew it
        measured = choice if choice.estimate is not None and choice.estimate.ok else None
        lander = session.make_lander(preset, slope_deg=slope_deg, next_preset=(up, down), slope=measured)
        end = lander.run(120 / speed + 60)
        if end == "LANDED":
            t_landed = rig.now
            rig.fly_until(
                lambda: lander.poll() == "LANDED" and rig.now - t_landed > 2.0, 10, "rest on the roof"
            )
            echo("take-off again; loosening the legs once clear of the roof")
            lander.takeoff_request = True
            end = lander.run(60 / speed + 30, until=("READY", "ABORTED", "ESTOP"))
            if end == "READY":  # watch the legs spring back for a moment
                rig.wait(3.0, tick=lander.poll)
        result_state = {"READY": "LANDED_AND_RESET"}.get(end, end)
        history = list(lander.machine.history)
        tele = session.telemetry
        uphill = session.legs.pairs.uphill if session.legs is not None else (0, 1)
    finally:
        rig.close()

    if (out / "flight.bin").is_file():  # ArduCopter's DataFlash log, copied as it stopped
        files["DataFlash log"] = str(out / "flight.bin")
    impact, slide, min_pitch = landing_figures(tele, history, cfg["reflex.impact_threshold_mps2"])
    angle_measured = uphill_angle_before_cut(tele, history, uphill)
    if plot:
        from slopelander.plots.flight import plot_flight

        files["picture"] = str(
            plot_flight(
                tele,
                history,
                out / "flight.png",
                title=(
                    f"slopelander demo: {slope_deg:g} deg roof, legs {up:.2f}/{down:.2f} N*m, "
                    f"{reverse_text(cfg['reflex.reverse_thrust_pct'])} - {result_state}"
                ),
                slope=slope_drawn,
            )
        )
    result = DemoResult(
        result_state,
        slope_deg,
        (up, down),
        preset.source,
        preset.angle_up_deg,
        angle_measured,
        expected,
        cut_m,
        impact,
        slide,
        min_pitch,
        [],
        history,
        files,
        time.monotonic() - wall0,
    )
    (out / "result.json").write_text(json.dumps(asdict(result), indent=1))
    files["result"] = str(out / "result.json")
    return result
