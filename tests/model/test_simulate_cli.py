"""``slopelander simulate`` as a user runs it: real process, real PNG."""

import subprocess
import sys


def _run(*args):
    return subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "simulate", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_simulate_prints_outcome_and_writes_plot_and_csv(tmp_path):
    png, csv = tmp_path / "landing.png", tmp_path / "landing.csv"
    r = _run(
        "--slope",
        "35",
        "--speed",
        "2.7",
        "--tau-up",
        "1.7",
        "--tau-down",
        "1.7",
        "--reverse",
        "--plot",
        str(png),
        "--csv",
        str(csv),
    )
    assert r.returncode == 0, r.stderr
    assert "outcome:" in r.stdout and "reverse command 100 % (100 % of full reverse thrust)" in r.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    lines = csv.read_text().splitlines()
    assert lines[0] == "t_s,x_m,z_m,pitch_rad,x_rate_m_s,z_rate_m_s,pitch_rate_rad_s"
    assert len(lines) > 300  # 2 s at 200 Hz


def test_bad_input_is_one_clear_line(tmp_path):
    r = _run("--slope", "95")
    assert r.returncode == 1
    assert "slope_deg" in r.stderr and "Traceback" not in r.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("schema: slopelander.model-parameters/1\nparameters: {body_mass: {unit: kg}}\n")
    r = _run("--params", str(bad))
    assert r.returncode == 1 and "missing 'value'" in r.stderr and "Traceback" not in r.stderr


def test_simulate_rigid_names_the_damage_and_the_load_behind_it():
    r = _run("--rigid", "--slope", "0", "--speed", "2.0")
    assert r.returncode == 0, r.stderr
    assert "outcome: gear damaged (impact load over its limit)" in r.stdout
    load = float(r.stdout.split("peak foot load: ")[1].split(" N")[0])
    limit = float(r.stdout.split("limit: ")[1].split(" N")[0])
    assert load > limit
    gentle = _run("--rigid", "--slope", "0", "--speed", "0.8")
    assert "outcome: ideal" in gentle.stdout and "peak foot load" in gentle.stdout


def test_simulate_ends_the_reverse_thrust_and_judges_after_it():
    roof = ["--slope", "42", "--speed", "2.25", "--tau-up", "1.1", "--tau-down", "1.7", "--angle-up", "22.3"]
    held = _run(*roof, "--reverse")
    step = _run(*roof, "--reverse", "--reverse-duration", "0.6")
    ramp = _run(*roof, "--reverse", "--reverse-duration", "0.6", "--reverse-ramp", "1.0")
    assert held.returncode == step.returncode == ramp.returncode == 0, (held.stderr, step.stderr, ramp.stderr)
    assert "outcome: under-used" in held.stdout or "outcome: ideal" in held.stdout
    assert "held 0.6 s, then stopped" in step.stdout and "outcome: slid" in step.stdout
    assert "ramped to zero over 1 s" in ramp.stdout and "outcome: slid" not in ramp.stdout
    bad = _run(*roof, "--reverse", "--reverse-ramp", "1.0")
    assert bad.returncode == 1 and "reverse_ramp" in bad.stderr and "Traceback" not in bad.stderr


def test_a_reverse_percent_is_told_as_the_rotor_command_and_the_thrust_it_gives():
    """--reverse-percent is a rotor speed command; thrust goes with its square. It printed
    "reverse thrust 70 %" for 49 % of the thrust."""
    r = _run("--slope", "20", "--speed", "2.0", "--reverse-percent", "70")
    assert r.returncode == 0, r.stderr
    assert "reverse command 70 % (49 % of full reverse thrust)" in r.stdout, r.stdout
    assert "reverse thrust 70 %" not in r.stdout
