"""A flight log in: the shipped DataFlash log of one landing (docs/examples/flightlog/
landing-20deg.bin, written by real ArduCopter SITL flying ``slopelander demo --autopilot ardupilot
--slope 20``, trimmed to the landing) read, its landing found, its first contact and conditions
held against the simulator's own state that ArduCopter logged beside them (SIM2), and the model
compared with it."""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from pymavlink import DFReader

from slopelander.cli import main
from slopelander.controller.config import load_config
from slopelander.ident.flightlog.compare import compare_log
from slopelander.ident.flightlog.conditions import Given, landing_conditions
from slopelander.ident.flightlog.landings import contact_time, find_landings, first_contact
from slopelander.ident.flightlog.observe import first_peak, lowpass, rest_time
from slopelander.ident.flightlog.reader import DATAFLASH, log_kind, read_log

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "flightlog" / "landing-20deg.bin"
ROOF_DEG = 20.0  # the demo's roof


def sim2(path: Path) -> np.ndarray:
    """SITL's own state as ArduCopter logged it: (t, velocity down, velocity north)."""
    r = DFReader.DFReader_binary(str(path))
    rows = []
    while (m := r.recv_match(type=["SIM2"])) is not None:
        rows.append((m.TimeUS * 1e-6, m.VD, m.VN))
    return np.array(rows)


def true_contact(path: Path, near: float | None = None) -> tuple[float, float]:
    """The SIM2 samples either side of the first contact (within 50 ms of ``near``, when given):
    the downward speed, growing in the fall, drops at once when a foot meets the roof."""
    s = sim2(path)
    if near is not None:
        s = s[np.abs(s[:, 0] - near) <= 0.05]
    i = int(np.argmax(np.diff(s[:, 1]) < -0.005))
    return float(s[i, 0]), float(s[i + 1, 0])


def test_the_log_is_told_by_its_content_not_its_name(tmp_path) -> None:
    renamed = tmp_path / "landing.dat"
    shutil.copy(EXAMPLE, renamed)
    assert log_kind(renamed) == DATAFLASH
    log = read_log(renamed)
    assert log.kind == DATAFLASH
    assert (log.imu.source, round(log.imu.rate_hz)) == ("IMU[0]", 400)
    assert (log.attitude.source, round(log.attitude.rate_hz)) == ("ANG", 400)
    assert log.ekf.source == "XKF1" and log.ranges.source == "RFND" and log.outputs.source == "RCOU"
    # the IMU filters from the log's own parameters (sitl-json.parm sets INS_ACCEL_FILTER 20)
    assert log.filters["accel_hz"] == 20.0 and log.filters["sample_hz"] == 800.0
    assert log.filters["source"] == "the log's parameters"


def test_the_landing_and_its_first_contact_against_the_simulators_state() -> None:
    log = read_log(EXAMPLE)
    [ev] = find_landings(log)
    contact, _ = contact_time(log, ev)
    lo, hi = true_contact(EXAMPLE)
    assert abs(contact - 0.5 * (lo + hi)) <= 0.003, (contact, lo, hi)  # within about a 400 Hz sample
    assert ev.cut < contact < ev.reverse < ev.reverse_left == ev.hold  # cut, contact, RVT, HOLD
    assert ev.reverse - contact < 0.03  # the script reversed within 30 ms of contact


def test_the_conditions_are_the_landing_as_flown() -> None:
    log = read_log(EXAMPLE)
    [ev] = find_landings(log)
    contact, _ = contact_time(log, ev)
    cond = landing_conditions(log, ev, contact, Given())
    c = cond.conditions
    s = sim2(EXAMPLE)
    lo, _ = true_contact(EXAMPLE)
    assert abs(c.slope_deg - ROOF_DEG) <= max(1.0, 2 * cond.slope.sigma_deg), cond.slope.describe()
    assert c.speed == pytest.approx(float(s[s[:, 0] == lo, 1][0]), abs=0.03)  # the last state before it
    assert (c.tau_up, c.tau_down) == (1.10, 1.10)  # the companion's "SL LEGS_WAIT" message
    assert "companion's message" in cond.sources["legs"]
    assert "not in the log" in cond.sources["leg angles"]
    cfg = load_config()
    assert c.reverse_percent == cfg["reflex.reverse_thrust_pct"]
    assert c.reverse_ramp == pytest.approx(cfg["reflex.reverse_ramp_ms"] / 1000.0, abs=0.05)
    said = next(t for t, text in log.texts if "SL SETTLED" in text)  # the companion ends the thrust
    assert c.reverse_delay + c.reverse_duration == pytest.approx(said - contact, abs=0.05)


def test_the_legs_as_the_board_reported_them_are_read_where_the_companion_wrote_them(tmp_path) -> None:
    """The shipped log predates the companion saying the board's angles at CHECKS; a landing's
    transitions.jsonl beside the log says them too ("legs within tolerance at UP/DOWN deg"), and
    the conditions take them from there instead of the lookup table."""
    log_path = tmp_path / "flight.bin"
    shutil.copy(EXAMPLE, log_path)
    log = read_log(log_path)
    [ev] = find_landings(log)
    contact, _ = contact_time(log, ev)
    entry = {
        "t": contact - 3.0,
        "from": "LEGS_WAIT",
        "to": "CHECKS",
        "reason": "legs within tolerance at 30.2/36.9 deg",
    }
    (tmp_path / "transitions.jsonl").write_text(json.dumps(entry) + "\n")
    cond = landing_conditions(log, ev, contact, Given())
    assert (cond.conditions.angle_up_deg, cond.conditions.angle_down_deg) == (30.2, 36.9)
    assert (
        cond.sources["leg angles"]
        == f"as the leg board reported them, transitions.jsonl beside the log ({contact - 3.0:.2f} s)"
    )


def test_the_model_at_those_conditions_follows_the_logged_landing(model) -> None:
    """The log was flown on the model's own physics (ArduCopter SITL behind the JSON bridge): its
    pitch, pitch rate and time to rest must agree; the first contact's accelerometer peak is the
    one known difference (docs/flight-logs.md)."""
    [r] = compare_log(model, EXAMPLE)
    assert r.errors["pitch, deg"] < 1.0
    assert r.errors["pitch rate, deg/s"] < 5.0
    low_log, low_model = r.figures["lowest pitch, deg"]
    assert abs(low_log - low_model) < 1.0
    rest_log, rest_model = r.figures["time to rest, s"]
    assert rest_log is not None and abs(rest_log - rest_model) < 0.05
    assert r.span == pytest.approx(2.0, abs=0.01)  # the trimmed log keeps 2 s of IMU after contact


def test_the_model_is_filtered_as_ardupilots_lowpassfilter2p() -> None:
    """DigitalBiquadFilter::compute_params (libraries/Filter/LowPassFilter2p.cpp): the biquad whose
    step response this is."""
    fs, fc = 800.0, 20.0
    ohm = math.tan(math.pi * fc / fs)
    c = 1.0 + 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm
    b0 = ohm * ohm / c
    a1 = 2.0 * (ohm * ohm - 1.0) / c
    a2 = (1.0 - 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm) / c
    x = np.r_[np.zeros(5), np.ones(200)]
    y = np.zeros_like(x)
    d1 = d2 = 0.0  # direct form II, as ArduPilot runs it
    for i, xi in enumerate(x):
        d0 = xi - a1 * d1 - a2 * d2
        y[i] = b0 * d0 + 2 * b0 * d1 + b0 * d2
        d2, d1 = d1, d0
    assert np.allclose(lowpass(x, fc, fs, 0.0), y, atol=1e-12)
    assert np.allclose(lowpass(np.full(50, 3.0), fc, fs, 3.0), 3.0)  # started settled: no ring-up


def test_first_contact_is_where_a_smooth_trend_bends() -> None:
    t = np.arange(200) / 400.0
    decay = np.column_stack([np.zeros(200), np.zeros(200), -9.8 * np.exp(-t / 0.05)])
    hit = decay.copy()
    k = 120
    hit[k + 1 :, 0] += 30.0 * (1 - np.exp(-(t[k + 1 :] - t[k]) / 0.01))
    i, _ = first_contact(t, hit)
    assert i == k
    assert first_contact(t, decay) is None  # a decaying thrust alone is no contact


def test_rest_and_the_first_peak() -> None:
    t = np.arange(0, 2, 0.01)
    rate = np.where(t < 0.4, 50.0, 1.0)
    speed = np.where(t < 0.6, 0.5, 0.02)
    assert rest_time(t, rate, speed) == pytest.approx(0.6)
    assert rest_time(t[:100], rate[:100], speed[:100]) is None  # still for less than 0.5 s
    mag = 10 + 20 * np.exp(-(((t - 0.03) / 0.01) ** 2)) + 40 * np.exp(-(((t - 0.2) / 0.02) ** 2))
    assert first_peak(t, mag) == pytest.approx((0.03, 30.0), abs=1e-6)


def test_compare_prints_the_table_and_writes_json_and_plot(tmp_path, capsys) -> None:
    log = tmp_path / "landing.dat"  # any name: the content says it is a log
    shutil.copy(EXAMPLE, log)
    assert main(["compare", str(log), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "landing.dat (DataFlash): landing 1 of 1, first contact at" in out
    assert "| lowest pitch, deg |" in out and "| time to rest, s |" in out
    doc = json.loads((tmp_path / "out" / "landing-landing1.json").read_text())
    assert doc["schema"] == "slopelander.log-landing/1"
    assert doc["conditions"]["tau_up"] == 1.1 and doc["log"]["kind"] == "DataFlash"
    assert set(doc["rms_difference"]) >= {"pitch, deg", "pitch rate, deg/s"}
    assert (tmp_path / "out" / "landing-landing1.png").stat().st_size > 20_000
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.startswith(".")]


def test_given_values_replace_the_logs_and_say_so(model) -> None:
    [r] = compare_log(model, EXAMPLE, Given(slope_deg=25.0, tau=(1.7, 2.3), angles=(30.0, 37.5)))
    c = r.cond.conditions
    assert (c.slope_deg, c.tau_up, c.tau_down, c.angle_up_deg) == (25.0, 1.7, 2.3, 30.0)
    assert r.cond.sources["slope"] == r.cond.sources["legs"] == r.cond.sources["leg angles"] == "given"


def test_trim_keeps_whole_messages_as_written(tmp_path, model) -> None:
    """A trimmed log is the autopilot's own bytes: each message it holds is one of the source's,
    byte for byte and in order, and compare reads the same landing from it."""
    from slopelander.ident.flightlog.trim import trim

    out = tmp_path / "again.bin"
    counts = trim(EXAMPLE, out)
    assert counts["IMU"] > 500 and counts["NVF"] > 10 and "SIM2" in counts
    src, got = EXAMPLE.read_bytes(), out.read_bytes()
    r = DFReader.DFReader_binary(str(out))
    r._rewind()
    at = 0
    while (m := r._parse_next()) is not None:
        piece = got[r.offset - m.fmt.len : r.offset]
        found = src.find(piece, at)
        assert found >= 0, m.get_type()
        at = found + len(piece)
    [a] = compare_log(model, EXAMPLE)
    [b] = compare_log(model, out)
    assert b.contact == a.contact and b.cond.conditions == a.cond.conditions


def test_without_the_scripts_states_the_motor_outputs_time_the_landing(tmp_path, model) -> None:
    """Firmware that does not log the script's NAMED_VALUE_FLOAT: the cut and the reverse thrust
    come from the 10 Hz RCOU, and the comparison says so."""
    from tests.ident.test_flightlog_bad_input import rewrite

    blind = rewrite(tmp_path / "no-states.bin", lambda m: m.get_type() != "NVF")
    [a] = compare_log(model, EXAMPLE)
    [b] = compare_log(model, blind)
    assert b.events.cut_source == "RCOU leaving forward thrust"
    assert b.contact == a.contact  # the accelerometer's, either way
    ca, cb = a.cond.conditions, b.cond.conditions
    assert cb.reverse_percent == ca.reverse_percent
    assert abs(cb.reverse_delay - ca.reverse_delay) <= 0.1  # one RCOU sample
    assert abs(cb.reverse_ramp - ca.reverse_ramp) <= 0.1
    assert any("timed by the 10 Hz motor outputs" in n for n in b.cond.notes)
    assert not any("cut" in n and "after first contact" in n for n in b.cond.notes)


def two_landings(dst: Path, gap_s: float = 30.0) -> tuple[Path, float]:
    """The shipped log flown twice: its messages as ArduCopter wrote them, then all of them again
    with every ``TimeUS`` moved ``gap_s`` past the first copy's end (nothing else changed), as a
    flight that lands, takes off and lands again writes one file. Returns the log and the shift."""
    import struct

    from tests.ident.test_flightlog_bad_input import messages

    data = EXAMPLE.read_bytes()
    msgs = messages(EXAMPLE)
    times = [m.TimeUS for m, _, _ in msgs if hasattr(m, "TimeUS")]
    shift = max(times) - min(times) + round(gap_s * 1e6)
    again = []
    for m, a, b in msgs:
        cols = m.fmt.columns
        if "TimeUS" not in cols:
            again.append(data[a:b])
            continue
        fields = list(struct.unpack(m.fmt.msg_struct, data[a + 3 : b]))
        fields[cols.index("TimeUS")] += shift
        again.append(data[a : a + 3] + struct.pack(m.fmt.msg_struct, *fields))
    dst.write_bytes(data + b"".join(again))
    return dst, shift * 1e-6


def test_a_log_of_two_landings_is_compared_landing_by_landing(tmp_path, capsys, model) -> None:
    """`slopelander compare FLIGHT.bin` finds each landing of a log and compares each on its own:
    the second landing (the first flown again later in the same file) is found at its own time,
    with the same conditions and contact, and each gets its JSON and plot."""
    log, shift = two_landings(tmp_path / "flight.bin")
    first, second = find_landings(read_log(log))
    assert second.cut == pytest.approx(first.cut + shift, abs=1e-6)
    assert first.end <= second.cut
    a, b = compare_log(model, log)
    assert b.contact == pytest.approx(a.contact + shift, abs=1e-6)
    # the second roof is measured from the points taken since the first landing (it used both
    # flights' rangefinder points: 106 where the roof had 52)
    assert b.cond.sources["slope"] == a.cond.sources["slope"], b.cond.sources["slope"]
    for f in dataclasses.fields(a.cond.conditions):
        want, got = getattr(a.cond.conditions, f.name), getattr(b.cond.conditions, f.name)
        assert got == pytest.approx(want, rel=1e-9, abs=1e-9), f.name
    [only] = compare_log(model, EXAMPLE)
    assert a.contact == only.contact and a.cond.conditions == only.cond.conditions
    assert main(["compare", str(log), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "landing 1 of 2" in out and "landing 2 of 2" in out
    assert {p.name for p in (tmp_path / "out").glob("*.json")} >= {
        "flight-landing1.json",
        "flight-landing2.json",
    }
    assert main(["compare", str(log), "--landing", "2", "--out", str(tmp_path / "two")]) == 0
    assert "landing 2 of 2" in capsys.readouterr().out
