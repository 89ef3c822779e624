"""Start the JSON physics server as a subprocess on a free UDP port (tests, benchmarks).

with start_json_physics(scenario={"slope_deg": 30, "start_on": "roof"}) as srv:
    ap = ArduPilotSide(srv.port)
"""

from __future__ import annotations

import socket
import subprocess
import tempfile
from pathlib import Path

import yaml

from slopelander_sitl.launching import start_ready_process


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PhysicsProcess:
    def __init__(
        self, proc: subprocess.Popen, port: int, ready: str, tmp: tempfile.TemporaryDirectory
    ) -> None:
        self.proc, self.port, self.ready_line, self._tmp = proc, port, ready, tmp
        self.stderr_path = Path(tmp.name) / "stderr.txt"
        self.summary = ""  # the "json_physics stopped ..." line, after stop()
        self._stderr_kept = ""

    def stderr(self) -> str:
        """What it wrote to stderr so far (kept after stop)."""
        return self.stderr_path.read_text() if self.stderr_path.exists() else self._stderr_kept

    def stop(self, timeout: float = 5.0) -> int:
        """SIGTERM, wait, and keep the summary line it prints on the way out."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                out, _ = self.proc.communicate(timeout=timeout)
                self.summary = next(
                    (ln for ln in out.splitlines() if ln.startswith("json_physics stopped")), ""
                )
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.stderr_path.exists():
            self._stderr_kept = self.stderr_path.read_text()
        self._tmp.cleanup()
        return self.proc.returncode

    def __enter__(self) -> PhysicsProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def start_json_physics(
    scenario: dict | None = None,
    legs: Path | None = None,
    port: int | None = None,
    timeout: float = 90.0,
    events: Path | None = None,
    rc_port: int | None = None,
    lockstep_port: int | None = None,
    real_time_below_m: float | None = None,
) -> PhysicsProcess:
    """Start ``python -m slopelander_sitl.json_physics`` (forked from a warm process where there is one:
    :func:`slopelander_sitl.processes.start`); returns once it is ready. Raises RuntimeError with
            its stderr if it fails. ``rc_port``: ArduPilot SITL's UDP RC input, where the scenario's
            ``rc`` schedule is sent; ``lockstep_port``: where the companion's echoes arrive (the physics then
        holds ArduPilot while the companion is behind,
        src/slopelander_sitl/json_physics/companion_gate.py), and with
    ``real_time_below_m`` keeps to real time that near the ground."""
    tmp = tempfile.TemporaryDirectory(prefix="sl-json-")
    port = port or free_udp_port()
    cmd = ["--port", str(port)]
    if scenario is not None:
        sp = Path(tmp.name) / "scenario.yaml"
        sp.write_text(yaml.safe_dump(scenario))
        cmd += ["--scenario", str(sp)]
    if legs is not None:
        cmd += ["--legs", str(legs)]
    if events is not None:
        cmd += ["--events", str(events)]
    if rc_port is not None:
        cmd += ["--rc-port", str(rc_port)]
    if lockstep_port is not None:
        cmd += ["--lockstep-port", str(lockstep_port)]
        if real_time_below_m is not None:
            cmd += ["--real-time-below", f"{real_time_below_m:g}"]
    proc, line = start_ready_process(
        "slopelander_sitl.json_physics", cmd, "json_physics ready", tmp, "json physics", timeout
    )
    return PhysicsProcess(proc, port, line, tmp)
