"""``python -m slopelander_sitl.json_physics`` refuses bad starts with one line and exit status 2."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

from slopelander_sitl.vehicle.launch import REPO, child_env


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "slopelander_sitl.json_physics", *args],
        capture_output=True,
        text=True,
        env=child_env(),
        cwd=REPO,
        timeout=120,
    )


def _one_line_error(r: subprocess.CompletedProcess) -> str | None:
    """The error line of a refused start (exit status 2, one line on stderr), else None."""
    lines = r.stderr.strip().splitlines()
    if (
        r.returncode != 2
        or len(lines) != 1
        or not lines[0].startswith("slopelander_sitl.json_physics: error: ")
    ):
        return None
    return lines[0]


def test_a_bad_scenario_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "s.yaml"
    bad.write_text("slope_deg: steep\n")
    assert "slope_deg must be a number" in (_one_line_error(_run("--scenario", str(bad))) or "")
    assert "cannot read" in (_one_line_error(_run("--scenario", str(tmp_path / "none.yaml"))) or "")


def test_a_port_in_use_is_named() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        assert f"cannot listen on udp 127.0.0.1:{port}" in (_one_line_error(_run("--port", str(port))) or "")
    assert "--port 70000" in (_one_line_error(_run("--port", "70000")) or "")


def test_a_missing_leg_board_is_named(tmp_path: Path) -> None:
    assert "leg board: cannot connect" in (_one_line_error(_run("--legs", str(tmp_path / "legs.ctl"))) or "")
