"""Start the simulated vehicle as a subprocess on a free port (for tests, benchmarks, demos).

with start_vehicle(scenario={"slope_deg": 20}) as v:
    conn = mavutil.mavlink_connection(v.mavlink_url)
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import yaml

from slopelander_sitl import processes
from slopelander_sitl.parent_watch import ENV

REPO = Path(__file__).resolve().parents[3]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def child_env() -> dict[str, str]:
    """The environment of a simulator this process starts: it finds the repository's packages, and
    it ends when this process does (:mod:`slopelander_sitl.parent_watch`)."""
    env = dict(os.environ)
    env[ENV] = str(os.getpid())
    env["PYTHONPATH"] = os.pathsep.join(
        [str(REPO / "src"), str(REPO)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else [])
    )
    return env


def stop_process(
    proc: subprocess.Popen | processes.ForkedProcess, tmp: tempfile.TemporaryDirectory, timeout: float = 5.0
) -> int:
    """Terminate a child (killed if it does not end within ``timeout``), remove its temporary
    directory, and return its exit status."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    tmp.cleanup()
    return proc.returncode


class VehicleProcess:
    def __init__(
        self,
        proc: subprocess.Popen | processes.ForkedProcess,
        port: int,
        ready: str,
        tmp: tempfile.TemporaryDirectory,
    ) -> None:
        self.proc, self.port, self.ready_line, self._tmp = proc, port, ready, tmp
        self.mavlink_url = f"tcp:127.0.0.1:{port}"

    def stop(self, timeout: float = 5.0) -> int:
        return stop_process(self.proc, self._tmp, timeout)

    def __enter__(self) -> VehicleProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def start_vehicle(
    scenario: dict | None = None,
    params: Path | dict | None = None,
    script: Path | None = None,
    no_script: bool = False,
    speed: float = 1.0,
    lockstep: bool = False,
    legboard_control: Path | None = None,
    legboard_period_ms: float | None = None,
    extra_endpoints: list[str] | None = None,
    timeout: float = 60.0,
    give_up_s: float | None = None,
) -> VehicleProcess:
    """Start ``python -m slopelander_sitl.vehicle`` listening on a free TCP port; returns once it is ready.
    ``params`` may be a dict written to a .parm file. Raises RuntimeError with its stderr if it fails."""
    tmp = tempfile.TemporaryDirectory(prefix="sl-vehicle-")
    port = free_port()
    cmd = [
        "--endpoint",
        f"tcpin:127.0.0.1:{port}",
        "--speed",
        str(speed),
    ]
    for e in extra_endpoints or []:
        cmd += ["--endpoint", e]
    if isinstance(params, dict):
        p = Path(tmp.name) / "vehicle.parm"
        p.write_text("".join(f"{k} {v}\n" for k, v in params.items()))
        params = p
    if params is not None:
        cmd += ["--params", str(params)]
    if no_script:
        cmd.append("--no-script")
    elif script is not None:
        cmd += ["--script", str(script)]
    if scenario is not None:
        sp = Path(tmp.name) / "scenario.yaml"
        sp.write_text(yaml.safe_dump(scenario))
        cmd += ["--scenario", str(sp)]
    if lockstep:
        cmd.append("--lockstep")
    if give_up_s is not None:
        cmd += ["--give-up", str(give_up_s)]
    if legboard_control is not None:
        cmd += ["--legboard-control", str(legboard_control)]
    if legboard_period_ms is not None:
        cmd += ["--legboard-period-ms", str(legboard_period_ms)]
    err = open(Path(tmp.name) / "stderr.txt", "w+")  # noqa: SIM115 - read back on failure
    proc = processes.start(
        "slopelander_sitl.vehicle", cmd, env=child_env(), cwd=REPO, stdout=subprocess.PIPE, stderr=err
    )
    deadline = time.monotonic() + timeout
    line = ""
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line.startswith("vehicle ready") or (not line and proc.poll() is not None):
            break
    if not line.startswith("vehicle ready"):
        proc.kill()
        proc.wait()
        err.seek(0)
        msg = err.read()
        err.close()
        tmp.cleanup()
        raise RuntimeError(f"vehicle did not start: {msg.strip()[-2000:]}")
    err.close()  # the vehicle has its own descriptor; the file stays for whoever reads it
    return VehicleProcess(proc, port, line.strip(), tmp)


class LegboardProcess:
    def __init__(
        self,
        proc: subprocess.Popen | processes.ForkedProcess,
        pty: str,
        control: Path,
        tmp: tempfile.TemporaryDirectory,
        clock: str = "wall",
    ) -> None:
        self.proc, self.pty, self.control, self._tmp = proc, pty, control, tmp
        self.clock = clock

    def stop(self, timeout: float = 5.0) -> int:
        return stop_process(self.proc, self._tmp, timeout)


def start_legboard(
    speed: float = 1.0, clock: str = "wall", timeout: float = 30.0, config: dict | None = None
) -> LegboardProcess:
    """Start ``python -m slopelander_sitl.legboard`` with a control socket in a temporary directory.
    ``clock="external"``: board time follows the vehicle given its control socket (and stands
    still until that vehicle runs); ``speed`` then does not matter. ``config``: firmware settings
    (``--config``), e.g. :func:`slopelander_sitl.legboard.runtime.silence_in_wall_time`."""
    tmp = tempfile.TemporaryDirectory(prefix="sl-legs-")
    link, ctl = Path(tmp.name) / "legs", Path(tmp.name) / "legs.ctl"
    extra = []
    if config:
        (Path(tmp.name) / "config.json").write_text(json.dumps(config))
        extra = ["--config", str(Path(tmp.name) / "config.json")]
    cmd = [
        "--link",
        str(link),
        "--control",
        str(ctl),
        "--speed",
        str(speed),
        "--clock",
        clock,
        *extra,
    ]
    proc = processes.start(
        "slopelander_sitl.legboard",
        cmd,
        env=child_env(),
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line.startswith("legboard ready"):
            fields = dict(f.split("=", 1) for f in line.split()[2:] if "=" in f)
            return LegboardProcess(proc, fields.get("link") or fields["pty"], ctl, tmp, clock)
        if not line and proc.poll() is not None:
            break
    proc.kill()
    proc.wait()
    tmp.cleanup()
    raise RuntimeError("leg board did not start")
