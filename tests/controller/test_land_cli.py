"""``slopelander land`` as a user runs it: bad input gives one clear line, never a traceback."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def land(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    """``land`` run from a folder of its own: a landing writes its evidence folder there."""
    import tempfile

    env = dict(os.environ, PYTHONPATH=f"{ROOT / 'src'}:{ROOT}")
    with tempfile.TemporaryDirectory() as cwd:
        return _run(args, timeout, env, cwd)


def _run(args, timeout: float, env: dict, cwd: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "slopelander.cli", "land", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        cwd=cwd,
    )


def port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--slope", "95"], "--slope must be within 0..89"),
        (["--slope", "20", "--table", "/nonexistent/table.yaml"], "table.yaml"),
        (["--slope", "20", "--config", "/nonexistent/c.yaml"], "cannot read"),
    ],
)
def test_bad_input_is_one_clear_line(args, message):
    out = land("--connect", f"udpin:127.0.0.1:{port()}", "--legs-port", "/nonexistent/tty", *args)
    assert out.returncode == 1, out.stderr
    assert message in out.stderr and "Traceback" not in out.stderr


def test_no_autopilot_is_reported(tmp_path):
    """After the settings' ``link.heartbeat_wait_s`` (10 s by default; 2 here) without a heartbeat."""
    from slopelander.controller.config import load_config
    from slopelander_sitl.vehicle.launch import start_legboard

    assert load_config()["link.heartbeat_wait_s"] == 10.0
    cfg = tmp_path / "wait.yaml"
    cfg.write_text("link:\n  heartbeat_wait_s: 2\n")
    board = start_legboard()  # the leg board is checked first, before the autopilot is waited for
    try:
        url = f"udpin:127.0.0.1:{port()}"
        out = land(
            "--connect", url, "--legs-port", board.pty, "--slope", "20", "--config", str(cfg), timeout=30
        )
    finally:
        board.stop()
    assert out.returncode == 1 and "no autopilot heartbeat within 2 s" in out.stderr
    assert "Traceback" not in out.stderr
