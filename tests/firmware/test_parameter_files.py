"""Every .parm line names a real ArduCopter parameter, with a value it accepts, and says why."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
FIRMWARE = REPO / "firmware_params"

PARM_FILES = sorted(FIRMWARE.glob("*.parm"))


def load_reference(ref: Path) -> dict[str, dict]:
    out = {}
    lines = (ref / "ardupilot-copter-params.tsv").read_text().splitlines()
    for line in lines[2:]:
        name, _units, rng, values, bitmask = (line.split("\t") + [""] * 5)[:5]
        out[name] = {"range": rng, "values": values, "bitmask": bitmask}
    return out


def parse_parm(path: Path) -> list[tuple[int, str, float, str]]:
    rows = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        body, _, comment = line.partition("#")
        if not body.strip():
            continue
        parts = re.split(r"[\s,]+", body.strip())
        assert len(parts) == 2, f"{path.name}:{n}: expected NAME VALUE, got {body.strip()!r}"
        rows.append((n, parts[0], float(parts[1]), comment.strip()))
    return rows


def problems(path: Path, ref: dict[str, dict]) -> list[str]:
    found = []
    for n, name, value, comment in parse_parm(path):
        where = f"{path.name}:{n} {name}"
        if name not in ref:
            found.append(f"{where}: no such ArduCopter parameter")
            continue
        if not comment:
            found.append(f"{where}: no comment saying why")
        spec = ref[name]
        if spec["range"]:
            lo, hi = (float(x) for x in spec["range"].split(".."))
            if not lo <= value <= hi:
                found.append(f"{where}: {value:g} outside {spec['range']}")
        if spec["values"] and not spec["bitmask"]:
            keys = [v.split("=")[0] for v in spec["values"].split(";") if "=" in v]
            # integer keys are an enum; decimal keys (MOT_SPIN_* "0.15=Default") are only suggestions;
            # the reference cuts long lists (sorted as text) at 300 characters: a value sorting after
            # the last listed key may have been cut, so it is not judged
            enum = all(re.fullmatch(r"-?\d+", k) for k in keys)
            cut = len(spec["values"]) >= 300
            allowed = {float(k) for k in keys}
            past_cut = cut and f"{value:g}" > keys[-1]
            if enum and allowed and value not in allowed and not past_cut:
                found.append(f"{where}: {value:g} is not one of its values")
        if spec["bitmask"]:
            keys = [v.split("=")[0] for v in spec["bitmask"].split(";") if "=" in v]
            bits = {int(k) for k in keys}
            # cut at 300 characters like the values (sorted as text): a bit sorting after the
            # last listed one may have been cut (RC_OPTIONS lists 0-4, 10-13: bit 5 is cut off)
            cut = len(spec["bitmask"]) >= 300
            unknown = {b for b in range(32) if b not in bits and not (cut and str(b) > keys[-1])}
            iv = int(value)
            if iv != value or iv < 0 or any((iv >> b) & 1 for b in unknown):
                found.append(f"{where}: {value:g} sets bits that do not exist")
    return found


def test_there_are_the_vehicle_and_the_sitl_files() -> None:
    assert {p.name for p in PARM_FILES} >= {"f450-fsa.parm", "sitl.parm", "sitl-json.parm"}


@pytest.mark.parametrize("path", PARM_FILES, ids=lambda p: p.name)
def test_every_line_is_a_real_parameter_with_a_valid_value_and_a_reason(path: Path, reference: Path) -> None:
    assert problems(path, load_reference(reference)) == []


def test_the_check_catches_bad_lines(tmp_path: Path, reference: Path) -> None:
    bad = tmp_path / "bad.parm"
    bad.write_text(
        "FRAME_CLASS 99   # no such frame\n"
        "MOT_PWM_MAX 2500 # beyond range\n"
        "NOT_A_PARAM 1    # invented\n"
        "ANGLE_MAX 4500\n"
    )
    found = problems(bad, load_reference(reference))
    assert any("FRAME_CLASS" in f and "values" in f for f in found)
    assert any("MOT_PWM_MAX" in f and "outside" in f for f in found)
    assert any("NOT_A_PARAM" in f and "no such" in f for f in found)
    assert any("ANGLE_MAX" in f and "comment" in f for f in found)


def test_route_a_output_range_is_the_same_on_vehicle_and_sitl() -> None:
    vals = {p.name: {name: v for _, name, v, _ in parse_parm(p)} for p in PARM_FILES}
    for sim in ("sitl.parm", "sitl-json.parm"):
        for name in (
            "FRAME_CLASS",
            "MOT_PWM_TYPE",
            "MOT_PWM_MIN",
            "MOT_PWM_MAX",
            "SCR_ENABLE",
            "RNGFND1_ORIENT",
        ):
            assert vals["f450-fsa.parm"][name] == vals[sim][name], (sim, name)
        assert vals[sim]["MOT_PWM_MIN"] > 1500 + 20  # the mixer never reaches the ESC's neutral
        assert vals[sim]["RNGFND1_TYPE"] == 100  # the simulator supplies the range


def test_json_sitl_outputs_mean_to_the_physics_what_the_route_says() -> None:
    """Through the physics server's ESC mapping: the mixer's minimum is stopped, its in-flight
    minimum spins forward, and the whole mixer range never reverses."""
    from slopelander_sitl.vehicle.esc import pwm_to_command

    v = {name: val for _, name, val, _ in parse_parm(FIRMWARE / "sitl-json.parm")}
    lo, hi = v["MOT_PWM_MIN"], v["MOT_PWM_MAX"]
    assert pwm_to_command(lo) == 0.0
    assert pwm_to_command(lo + v["MOT_SPIN_MIN"] * (hi - lo)) > 0.0
    assert min(pwm_to_command(p) for p in range(int(lo), int(hi) + 1)) >= 0.0
    assert pwm_to_command(hi) == 1.0


def test_suggestions_and_cut_lists_are_not_false_alarms(tmp_path: Path, reference: Path) -> None:
    ok = tmp_path / "ok.parm"
    ok.write_text(
        "MOT_SPIN_MIN 0.12  # a suggestion list, not an enum\n"
        "RNGFND1_TYPE 35    # TeraRanger Evo serial: listed past the reference's cut\n"
    )
    assert problems(ok, load_reference(reference)) == []
    bad = tmp_path / "bad.parm"
    bad.write_text("RNGFND1_TYPE 101  # sorts before the cut and is not listed\n")
    assert problems(bad, load_reference(reference)) != []


def test_the_simulated_vehicle_and_the_script_use_real_parameter_names(
    tmp_path: Path, reference: Path
) -> None:
    """The names the simulated vehicle serves and the script reads are ArduCopter's own, with
    values it accepts, so a .parm file written for one is understood by the other."""
    from slopelander_sitl.vehicle.params import VEHICLE_DEFAULTS

    ref = load_reference(reference)
    script = (FIRMWARE / "scripts" / "slopelander.lua").read_text()
    read_by_script = set(re.findall(r'param:get\("([A-Z0-9_]+)"\)', script))
    assert "MAV_SYSID" in read_by_script
    assert sorted(n for n in read_by_script if n not in ref) == []
    defaults = tmp_path / "vehicle-defaults.parm"
    defaults.write_text("".join(f"{n} {v:g}  # vehicle default\n" for n, v in VEHICLE_DEFAULTS.items()))
    assert problems(defaults, ref) == []
    units = {
        r.split("\t")[0]: r.split("\t")[1]
        for r in (reference / "ardupilot-copter-params.tsv").read_text().splitlines()[2:]
    }
    assert units["RNGFND1_MIN"] == units["RNGFND1_MAX"] == "m"
    assert VEHICLE_DEFAULTS["RNGFND1_MIN"] < 1.0 < VEHICLE_DEFAULTS["RNGFND1_MAX"] < 100.0  # metres, not cm


def test_no_descent_target_outlives_the_reflex() -> None:
    """Issue 40 finding 1: the companion's GUIDED descent target runs on for GUID_TIMEOUT after its
    last word, its reflex for ``reflex.validity_ms``. The script, alive, stops the descent when the
    validity lapses (CLIMB); dead too (an instruction budget it cannot catch), only GUID_TIMEOUT
    does. So GUID_TIMEOUT is at most the validity, on the vehicle and in both simulators, and the
    companion's re-sends still refresh the target through a lost one."""
    from slopelander.controller.config import load_config

    cfg = load_config()
    for path in PARM_FILES:
        v = {name: val for _, name, val, _ in parse_parm(path)}
        assert v["GUID_TIMEOUT"] * 1000 <= cfg["reflex.validity_ms"], path.name
        assert v["GUID_TIMEOUT"] >= 3 / cfg["descent.resend_hz"], path.name
