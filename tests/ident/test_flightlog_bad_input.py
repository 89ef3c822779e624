"""slopelander compare on a log it cannot use: one line naming the file and what is missing, and
no report folder. Each variant is the shipped ArduCopter log (docs/examples/flightlog/) cut short or
with whole messages left out, as a damaged download or another logging setup would leave it; each
runs as a real process."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from pymavlink import DFReader

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "flightlog" / "landing-20deg.bin"


def compare(folder: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}"}
    return subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "compare", *args, "--out", "out"],
        capture_output=True,
        text=True,
        env=env,
        cwd=folder,
        timeout=300,
    )


def assert_refused(r: subprocess.CompletedProcess, folder: Path, name: str, *words: str) -> str:
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith(f"slopelander compare: error: {name}: "), lines[0]
    for w in words:
        assert w in lines[0], lines[0]
    assert "Traceback" not in r.stderr
    assert not (folder / "out").exists()
    return lines[0]


def messages(path: Path) -> list[tuple[object, int, int]]:
    """(message, start byte, end byte) of every message of a DataFlash log, in order."""
    r = DFReader.DFReader_binary(str(path))
    r._rewind()
    out = []
    while (m := r._parse_next()) is not None:
        out.append((m, r.offset - m.fmt.len, r.offset))
    return out


def rewrite(dst: Path, keep) -> Path:
    """The example with only the whole messages ``keep(message)`` accepts."""
    data = EXAMPLE.read_bytes()
    dst.write_bytes(b"".join(data[a:b] for m, a, b in messages(EXAMPLE) if keep(m)))
    return dst


def moment(kind: str, value: float) -> float:
    """The time (s) of the example's first SL_STATE announcement of ``value``."""
    return next(
        m.TimeUS * 1e-6
        for m, _, _ in messages(EXAMPLE)
        if m.get_type() == kind and m.Name == "SL_STATE" and m.Value == value
    )


def test_a_file_that_is_no_log(tmp_path) -> None:
    (tmp_path / "notes.bin").write_text("take-off 12:03, landing 12:05\n")
    r = compare(tmp_path, "notes.bin")
    assert_refused(r, tmp_path, "notes.bin", "not a DataFlash log or a MAVLink telemetry log")


def test_an_empty_file(tmp_path) -> None:
    (tmp_path / "flight.bin").write_bytes(b"")
    assert_refused(compare(tmp_path, "flight.bin"), tmp_path, "flight.bin", "the file is empty")


def test_a_log_cut_short_in_the_landing(tmp_path) -> None:
    rvt = moment("NVF", 12.0)
    end = next(b for m, a, b in messages(EXAMPLE) if getattr(m, "TimeUS", 0) * 1e-6 > rvt + 0.1)
    (tmp_path / "cut.bin").write_bytes(EXAMPLE.read_bytes()[: end + 7])  # into the next message
    r = compare(tmp_path, "cut.bin")
    line = assert_refused(r, tmp_path, "cut.bin", "landing 1: the log holds only 0.1")
    assert "s after first contact" in line and "the file ends inside its last message" in line


def test_a_log_cut_short_before_its_landing(tmp_path) -> None:
    cut = moment("NVF", 11.0)
    start = next(a for m, a, _ in messages(EXAMPLE) if getattr(m, "TimeUS", 0) * 1e-6 >= cut)
    (tmp_path / "early.bin").write_bytes(EXAMPLE.read_bytes()[: start + 5])
    line = assert_refused(compare(tmp_path, "early.bin"), tmp_path, "early.bin", "no landing in this log")
    assert "states seen: 0, 10" in line and "the file ends inside its last message" in line


def test_a_complete_log_with_no_landing(tmp_path) -> None:
    cut = moment("NVF", 11.0)
    rewrite(tmp_path / "hover.bin", lambda m: getattr(m, "TimeUS", 0) * 1e-6 < cut)
    line = assert_refused(compare(tmp_path, "hover.bin"), tmp_path, "hover.bin", "no landing in this log")
    assert "never went from the cut (11)" in line and "ends inside" not in line


def test_a_log_without_the_companions_messages_asks_for_the_torques(tmp_path) -> None:
    rewrite(tmp_path / "quiet.bin", lambda m: not (m.get_type() == "MSG" and "SRC=" in m.Message))
    assert_refused(
        compare(tmp_path, "quiet.bin"),
        tmp_path,
        "quiet.bin",
        "legs' friction torques",
        "--tau-up UP --tau-down DOWN",
    )
    r = compare(tmp_path, "quiet.bin", "--tau-up", "1.1", "--tau-down", "1.1")
    assert r.returncode == 0, r.stderr
    assert "legs: given" in r.stdout


def test_a_log_without_the_rangefinder_asks_for_the_slope(tmp_path) -> None:
    rewrite(tmp_path / "blind.bin", lambda m: m.get_type() != "RFND")
    line = assert_refused(compare(tmp_path, "blind.bin"), tmp_path, "blind.bin", "--slope DEG")
    assert "the roof well enough to measure its slope" in line


def test_a_landing_the_log_does_not_have(tmp_path) -> None:
    assert_refused(compare(tmp_path, str(EXAMPLE), "--landing", "2"), tmp_path, str(EXAMPLE), "1 landing(s)")


def test_log_options_on_a_dataset_folder(tmp_path) -> None:
    (tmp_path / "drops").mkdir()
    r = compare(tmp_path, "drops", "--slope", "20")
    assert r.returncode == 1 and "--slope: only for a flight log" in r.stderr
