"""Start real ArduCopter SITL, with slopelander's physics behind it, for a test, a benchmark or
the demo; reach its MAVLink from this process.

    with start_arducopter(scenario={"slope_deg": 35}, legs=board.control) as ap:
        link = Link(ap.mavlink_url)          # SERIAL1, the companion's port
        mavproxy --master ap.gcs_url         # SERIAL2, a ground station

ArduCopter and the physics run in a loopback-only network namespace (:mod:`slopelander_sitl.netns`), each
instance in its own temporary folder; this process joins a free loopback TCP port to each of
the namespace's UNIX sockets (:mod:`slopelander_sitl.bridge`). The leg board's control socket is a file too,
so the simulated legs work across the namespace unchanged.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import yaml

from slopelander_sitl.bridge import Bridge, tcp_to_unix
from slopelander_sitl.launching import LaunchError, start_ready_process
from slopelander_sitl.vehicle.launch import stop_process

ENV = "SLOPELANDER_ARDUCOPTER"
#: ArduCopter's speed-up from boot until it could arm (``slopelander_sitl.ardupilot.fast_boot``): in lock-step
#: with the physics, so as fast as the two can step
BOOT_SPEEDUP = 20.0


class ArduCopterMissingError(LaunchError):
    """No ArduCopter SITL binary to fly against."""


def arducopter_binary(path: str | Path | None = None) -> Path:
    """The ArduCopter SITL binary: ``path``, else ``$SLOPELANDER_ARDUCOPTER``. Raises
    :class:`ArduCopterMissingError` saying which was tried and how to get one."""
    given = path if path is not None else os.environ.get(ENV)
    if not given:
        raise ArduCopterMissingError(
            f"no ArduCopter SITL binary: set {ENV} (or pass --arducopter) to the arducopter built by "
            "`./waf configure --board sitl && ./waf copter` in an ArduPilot checkout"
        )
    p = Path(given).expanduser()
    if not p.is_file() or not os.access(p, os.X_OK):
        src = "--arducopter" if path is not None else ENV
        raise ArduCopterMissingError(f"{src}={given} is not an executable file")
    return p


class ArduCopterProcess:
    """A running ArduCopter and its physics. ``mavlink_url`` is its SERIAL1 (the companion's
    port), ``gcs_url`` its SERIAL2; ``folder`` is its working folder, removed by :meth:`stop`
    unless ``keep`` was asked for. With ``keep_log``, :meth:`stop` copies ArduCopter's DataFlash
    log there once it has ended (:meth:`copy_log`)."""

    def __init__(
        self,
        proc,
        ready: str,
        tmp: tempfile.TemporaryDirectory,
        keep: bool,
        keep_log: Path | None = None,
    ) -> None:
        self.proc, self.ready_line, self._tmp, self.keep = proc, ready, tmp, keep
        self.keep_log = keep_log
        self.folder = Path(tmp.name) / "ap"
        self._bridges: list[Bridge] = []
        b1, p1 = tcp_to_unix(str(self.folder / "serial1.sock"), "serial1")
        b2, p2 = tcp_to_unix(str(self.folder / "serial2.sock"), "serial2")
        self._bridges = [b1, b2]
        self.mavlink_url = f"tcp:127.0.0.1:{p1}"
        self.gcs_url = f"tcp:127.0.0.1:{p2}"
        self.summary = ""

    @property
    def events_path(self) -> Path:
        return self.folder / "events.jsonl"

    def statustexts(self) -> list[str]:
        """Every STATUSTEXT ArduCopter sent so far, as ``"<boot s> <severity> <text>"`` lines."""
        p = self.folder / "statustext.log"
        return p.read_text().splitlines() if p.exists() else []

    def console(self) -> str:
        p = self.folder / "arducopter.log"
        return p.read_text(errors="replace") if p.exists() else ""

    def dataflash_logs(self) -> list[Path]:
        """ArduCopter's DataFlash logs so far (``logs/*.BIN`` in its folder), oldest first."""
        return sorted((self.folder / "logs").glob("*.BIN"))

    def copy_log(self, dest: Path) -> list[Path]:
        """Copy ArduCopter's DataFlash log to ``dest`` (one log per boot with the parameter file's
        ``LOG_FILE_DSRMROT 0``; more, if other parameters made more, as ``dest``'s stem -1, -2, ...);
        the copies made."""
        logs = self.dataflash_logs()
        if len(logs) == 1:
            targets = [dest]
        else:
            targets = [dest.with_name(f"{dest.stem}-{n}{dest.suffix}") for n in range(1, len(logs) + 1)]
        for src, dst in zip(logs, targets, strict=True):
            shutil.copyfile(src, dst)
        return targets

    def stop(self, timeout: float = 15.0) -> int:
        for b in self._bridges:
            b.close()
        if self.proc.poll() is None:
            self.proc.terminate()
        try:  # a pod that already ended has its summary in its output too
            out, _ = self.proc.communicate(timeout=timeout)
            self.summary = next(
                (ln for ln in (out or "").splitlines() if ln.startswith("arducopter stopped")), ""
            )
        except Exception:  # a stuck pod is killed, whatever went wrong
            self.proc.kill()
            self.proc.wait()
        if not self.summary:  # killed, or its output lost: the pod also wrote the physics' summary
            with contextlib.suppress(OSError):
                kept = (self.folder / "physics-summary.txt").read_text().splitlines()
                self.summary = f"arducopter stopped status={self.proc.returncode} {kept[0]}" if kept else ""
        if self.keep_log is not None:
            try:
                self.copy_log(self.keep_log)
            except OSError as exc:  # the vehicle's stop must not fail for want of its log
                print(f"slopelander_sitl.ardupilot: its DataFlash log was not kept: {exc}", flush=True)
        if self.keep:
            self._tmp._finalizer.detach()  # the folder stays for the user to read
            return self.proc.returncode
        return stop_process(self.proc, self._tmp)

    def __enter__(self) -> ArduCopterProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def start_arducopter(
    scenario: dict | None = None,
    legs: Path | None = None,
    binary: str | Path | None = None,
    speedup: float = 4.0,
    boot_speedup: float | None = BOOT_SPEEDUP,
    params: list[Path] | dict | None = None,
    script: bool | Path = True,
    keep: bool = False,
    timeout: float = 120.0,
    companion_lockstep: bool = True,
    keep_log: Path | None = None,
) -> ArduCopterProcess:
    """Start ArduCopter SITL (:func:`arducopter_binary`) with the project's JSON parameter file
    (plus ``params``: more .parm files, or a dict of name → value), the on-board script unless
    ``script`` is False (another Lua script when it is a path), and the physics of
    ``scenario``. ``speedup`` is ArduCopter's ``--speedup`` (it runs in lock-step with the physics,
    so a loaded machine only slows it down). With ``boot_speedup`` it boots at that speed-up until
    it could arm (``slopelander_sitl.ardupilot.fast_boot``: the EKF's alignment, origin and position take
    about 40 s of vehicle time) and returns at ``speedup``, ready to arm; with None it returns at
    its first HEARTBEAT, booting at ``speedup``. With ``companion_lockstep`` the physics holds
    ArduCopter while the companion on SERIAL1 is behind, once it echoes
    (``slopelander_sitl.json_physics.companion_gate``). With ``keep_log`` its DataFlash log is copied there
    when it stops (the parameter file has it log while armed, one file per boot)."""
    exe = arducopter_binary(binary)
    tmp = tempfile.TemporaryDirectory(prefix="sl-arducopter-")
    folder = Path(tmp.name) / "ap"
    folder.mkdir()
    cmd = ["--dir", str(folder), "--binary", str(exe)]
    cmd += ["--speedup", f"{speedup:g}"]
    if boot_speedup is not None:
        cmd += ["--boot-speedup", f"{boot_speedup:g}"]
    if scenario is not None:
        sp = Path(tmp.name) / "scenario.yaml"
        sp.write_text(yaml.safe_dump(scenario))
        cmd += ["--scenario", str(sp)]
    if legs is not None:
        cmd += ["--legs", str(legs)]
    if isinstance(params, dict):
        pp = Path(tmp.name) / "extra.parm"
        pp.write_text("".join(f"{k} {v}\n" for k, v in params.items()))
        params = [pp]
    for p in params or []:
        cmd += ["--params", str(p)]
    if not companion_lockstep:
        cmd.append("--no-companion-lockstep")
    if not script:
        cmd.append("--no-script")
    elif isinstance(script, Path):
        cmd += ["--script", str(script)]
    proc, line = start_ready_process(
        "slopelander_sitl.ardupilot", cmd, "arducopter ready", tmp, "ArduCopter SITL", timeout, isolate=True
    )
    return ArduCopterProcess(proc, line, tmp, keep, keep_log)


def read_events(path: Path, start: int = 0) -> tuple[list[dict], int]:
    """The physics' events written to ``path`` from byte ``start`` on, and where to read next."""
    if not path.exists():
        return [], start
    with open(path, "rb") as f:
        f.seek(start)
        data = f.read()
    end = data.rfind(b"\n") + 1  # a line still being written is read next time
    events = [json.loads(ln) for ln in data[:end].splitlines() if ln.strip()]
    return events, start + end
