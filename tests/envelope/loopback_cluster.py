"""A real Dask cluster on 127.0.0.1 for tests and benchmarks: a ``dask scheduler`` process and
``dask worker`` processes started as a user starts them (docs/cluster.md), each worker one thread,
importing the same slopelander as this process (or another copy, to test a mismatch)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import slopelander

SRC = Path(slopelander.__file__).resolve().parents[1]
START_TIMEOUT = 180.0
"""Seconds for the processes to come up on a loaded 2-core machine (a worker's imports alone
take 2-5 s there, and a first warm-up loads the compiled model)."""


def _die_with_parent() -> None:
    """In the child before it runs: SIGTERM when this process ends (Linux's PR_SET_PDEATHSIG),
    so no scheduler or worker outlives a test run that was killed."""
    import ctypes

    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # 1: PR_SET_PDEATHSIG


class LoopbackCluster:
    """``workers`` worker processes (with a nanny, as ``dask worker`` starts them, unless
    ``nanny`` is False) and one scheduler; ``pythonpath``: where the workers import slopelander
    from (default: where this process does); ``scheduler_env``: Dask settings of the scheduler
    (``DASK_DISTRIBUTED__...`` variables); ``sessions``: each process in a session of its own,
    as when started from its own terminal or service (Linux then shares the CPU between
    sessions, not between processes, when other work keeps every core busy); ``worker_env``:
    more environment variables for the workers."""

    def __init__(
        self,
        workers: int = 2,
        *,
        nanny: bool = True,
        pythonpath: Path | None = None,
        scheduler_env: dict[str, str] | None = None,
        sessions: bool = False,
        worker_env: dict[str, str] | None = None,
    ) -> None:
        self.dir = Path(tempfile.mkdtemp(prefix="sl-dask-"))
        self.file = self.dir / "scheduler.json"
        self.nanny = nanny
        self.pythonpath = pythonpath or SRC
        self.scheduler_env = scheduler_env or {}
        self.sessions = sessions
        self.worker_env = worker_env or {}
        self.procs: list[subprocess.Popen] = []
        self.client = None
        self.address = ""
        try:
            self._start(workers)
        except BaseException:
            self.close()
            raise

    def _env(self, pythonpath: Path) -> dict[str, str]:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(pythonpath), str(SRC.parent)])
        env.pop("SLOPELANDER_MODEL_READY", None)
        return env

    def _spawn(self, name: str, args: list[str], env: dict[str, str]) -> subprocess.Popen:
        log = open(self.dir / f"{name}.log", "wb")  # noqa: SIM115 - kept open for the process's life
        p = subprocess.Popen(
            [sys.executable, "-m", "dask", *args],
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=self.sessions,
            preexec_fn=_die_with_parent if sys.platform == "linux" else None,
        )
        log.close()
        self.procs.append(p)
        return p

    def _start(self, workers: int) -> None:
        import json

        from distributed import Client

        # stopped with this process should it die without closing it (_die_with_parent); else gone
        # by itself an hour after its last task (not sooner: a scheduler idle for 10 minutes while
        # this process worked alone under load closed under a test), its workers a minute later
        args = ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--idle-timeout", "3600"]
        env = {**self._env(SRC), **self.scheduler_env}
        self._spawn("scheduler", [*args, "--scheduler-file", str(self.file)], env)
        end = time.monotonic() + START_TIMEOUT
        while not self.file.exists() or not self.file.read_text().strip():
            if self.procs[0].poll() is not None or time.monotonic() > end:
                raise RuntimeError(f"the scheduler did not start:\n{self.log('scheduler')}")
            time.sleep(0.1)
        self.address = json.loads(self.file.read_text())["address"]
        for i in range(workers):
            self.add_worker(f"w{i}")
        self.client = Client(self.address, timeout="60s")
        try:
            if workers:
                self.client.wait_for_workers(workers, timeout=START_TIMEOUT)
        except TimeoutError:
            logs = "\n".join(self.log(f"w{i}") for i in range(workers))
            raise RuntimeError(f"the workers did not join:\n{logs}") from None

    def add_worker(self, name: str, pythonpath: Path | None = None) -> subprocess.Popen:
        args = ["worker", self.address, "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard"]
        args += ["--name", name, "--death-timeout", "60", "--nanny" if self.nanny else "--no-nanny"]
        args += ["--local-directory", str(self.dir)]
        return self._spawn(name, args, {**self._env(pythonpath or self.pythonpath), **self.worker_env})

    def worker_pids(self) -> dict[str, int]:
        """The worker processes' ids by address (not their nannies')."""
        return self.client.run(os.getpid)

    def log(self, name: str) -> str:
        path = self.dir / f"{name}.log"
        return path.read_text(errors="replace")[-3000:] if path.exists() else f"({name}: no log)"

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        # the workers first, while the scheduler still answers their goodbyes (stopped together,
        # a worker sometimes waited 8 s on it), then the scheduler
        for group in (self.procs[1:], self.procs[:1]):
            for p in group:
                if p.poll() is None:
                    p.send_signal(signal.SIGTERM)
            for p in group:
                try:
                    # a worker started in a killed one's place may still be loading the model
                    p.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        shutil.rmtree(self.dir, ignore_errors=True)

    def __enter__(self) -> LoopbackCluster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def other_slopelander(dest: Path, version: str) -> Path:
    """A copy of this slopelander that says it is ``version``: what a worker with another
    installation imports. Returns the folder to put on its PYTHONPATH."""
    pkg = dest / "slopelander"
    shutil.copytree(Path(slopelander.__file__).parent, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    init = pkg / "__init__.py"
    text = init.read_text()
    assert f'__version__ = "{slopelander.__version__}"' in text
    init.write_text(text.replace(f'__version__ = "{slopelander.__version__}"', f'__version__ = "{version}"'))
    return dest
