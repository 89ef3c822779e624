"""Start a simulator (``python -m MODULE ARGS``) as a fresh interpreter, or forked from the
standard library's :mod:`multiprocessing` forkserver with :mod:`slopelander_sitl.warm` preloaded.

Why a warm start at all: a fresh simulated vehicle or leg board spends over a second of CPU
before its first tick (imports, the compiled model loaded from numba's cache), and a test run
starts one of each for each of its many landings. ``python3 benchmarks/vehicle_start.py``
measures both ways in one run; on 2026-12-06 at load 7 a vehicle and its leg board took 1.34 s
of CPU and 2.82 s of wall time to "ready" started fresh, 0.08 s and 0.20 s forked (medians of
5), the forkserver's own start 1.19 s of CPU once per worker. So the test suite forks
(``tests/conftest.py`` calls :func:`use_forkserver`); everything else (``slopelander demo``, a
benchmark, a user) starts fresh processes, the default, and so does what a forked simulator
starts itself (ArduCopter's pod its physics). The forkserver and what it forks are plain
:mod:`multiprocessing`; this module only adds what ``subprocess.Popen`` offers and the launchers
use (stdout as a pipe, stderr to a file, a working directory, an environment,
``poll``/``wait``/``terminate``).

A child forked so watches the forkserver, its real parent (:mod:`slopelander_sitl.parent_watch`): the
forkserver ends when the process that started it ends, and its children then stop themselves.
"""

from __future__ import annotations

import atexit
import contextlib
import multiprocessing
import multiprocessing.forkserver
import multiprocessing.reduction
import multiprocessing.util  # its exit handler registered before ours (use_forkserver)
import os
import runpy
import signal
import subprocess
import sys
from pathlib import Path
from typing import IO

from slopelander_sitl.parent_watch import ENV, GRACE_S

#: what the forkserver imports before it forks anything (the simulators' modules and the model)
PRELOAD = ("slopelander_sitl.warm",)

_CONTEXT: multiprocessing.context.BaseContext | None = None
_LIVE: list[ForkedProcess] = []  # started here and not yet seen ended


def use_forkserver(preload: tuple[str, ...] = PRELOAD) -> None:
    """Fork this process's simulators from a forkserver from now on (it starts at the first)."""
    global _CONTEXT
    if _CONTEXT is None:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(list(preload))
        _CONTEXT = ctx
        # registered after multiprocessing's own exit handler, so it runs first: that one joins
        # every child still running and would wait for a simulator nobody stopped
        atexit.register(_stop_left_children)


def forkserver_active() -> bool:
    return _CONTEXT is not None


class Passed:
    """A file descriptor handed to a forked child: pickled for the forkserver as
    :class:`multiprocessing.reduction.DupFd`, so the child receives a copy of it."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def __reduce__(self) -> tuple:
        return _received, (multiprocessing.reduction.DupFd(self.fd),)


def _received(dup: object) -> Passed:
    return Passed(dup.detach())  # type: ignore[attr-defined]


def _run_module(
    module: str, argv: list[str], env: dict[str, str], cwd: str, out: Passed, err: Passed, isolate: bool
) -> None:
    """In the forked child: become ``python -m module *argv`` with the caller's streams,
    environment and working directory (``isolate``: in a loopback-only network namespace)."""
    # multiprocessing hands each child the caller's end of the pipe the forkserver watches (so
    # that the child could fork from it too): held here, the forkserver would outlive its caller,
    # and so would this child, which watches the forkserver (slopelander_sitl.parent_watch)
    alive = multiprocessing.forkserver._forkserver._forkserver_alive_fd
    if alive is not None:
        os.close(alive)
        multiprocessing.forkserver._forkserver._forkserver_alive_fd = None
    os.dup2(out.fd, 1)
    os.dup2(err.fd, 2)
    for fd in {out.fd, err.fd} - {1, 2}:
        os.close(fd)
    os.chdir(cwd)
    env = dict(env)
    if ENV in env:
        env[ENV] = str(os.getppid())  # the forkserver: it ends with the caller
    os.environ.clear()
    os.environ.update(env)
    sys.argv = [module, *argv]
    if isolate:
        from slopelander_sitl.netns import NamespaceError, enter_isolated

        try:
            enter_isolated()
        except NamespaceError as exc:
            sys.exit(f"{module}: error: {exc}")
    runpy.run_module(module, run_name="__main__", alter_sys=True)


class ForkedProcess:
    """A simulator forked from the forkserver, answering as :class:`subprocess.Popen` does."""

    def __init__(self, proc: multiprocessing.process.BaseProcess, args: list[str], stdout: IO[str] | None):
        self._proc, self.args, self.stdout = proc, args, stdout
        self.pid: int = proc.pid  # type: ignore[assignment]

    @property
    def returncode(self) -> int | None:
        return self._proc.exitcode

    def poll(self) -> int | None:
        return self._proc.exitcode

    def wait(self, timeout: float | None = None) -> int:
        self._proc.join(timeout)
        if self._proc.exitcode is None:
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
        return self._proc.exitcode

    def communicate(self, timeout: float | None = None) -> tuple[str, None]:
        self.wait(timeout)
        return (self.stdout.read() if self.stdout is not None else ""), None

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


def _stop_left_children() -> None:
    """At exit: stop the simulators still running (a test that failed before stopping its own)."""
    left = [p for p in _LIVE if p.poll() is None]
    for p in left:
        p.terminate()
    for p in left:
        try:
            p.wait(GRACE_S)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _child_fds(stdout: int | IO | None, stderr: int | IO | None) -> tuple[list[int], list[int], int | None]:
    """The descriptors the child gets as stdout and stderr, those to close here once it has them,
    and the read end of its stdout pipe (``subprocess.PIPE``) if any."""
    close_after: list[int] = []
    read_end = None

    def fd_for(target: int | IO | None, default: int) -> int:
        nonlocal read_end
        if target is None:
            return default
        if target == subprocess.PIPE:
            read_end, w = os.pipe()
            close_after.append(w)
            return w
        if target == subprocess.DEVNULL:
            fd = os.open(os.devnull, os.O_RDWR)
            close_after.append(fd)
            return fd
        return target.fileno()  # type: ignore[union-attr]

    return [fd_for(stdout, 1), fd_for(stderr, 2)], close_after, read_end


def start(
    module: str,
    argv: list[str],
    *,
    env: dict[str, str],
    cwd: Path | str,
    stdout: int | IO | None = None,
    stderr: int | IO | None = None,
    isolate: bool = False,
) -> subprocess.Popen | ForkedProcess:
    """``python -m module *argv``, text streams: forked from the forkserver after
    :func:`use_forkserver`, else a fresh interpreter. ``stdout``/``stderr``: ``subprocess.PIPE``
    (stdout only), ``subprocess.DEVNULL``, an open file, or None (this process's own).
    ``isolate``: in a loopback-only network namespace of its own (:mod:`slopelander_sitl.netns`)."""
    if _CONTEXT is None:
        cmd = [sys.executable, "-m", module, *argv]
        if isolate:
            from slopelander_sitl.netns import isolated_command

            cmd = isolated_command(cmd)
        return subprocess.Popen(cmd, stdout=stdout, stderr=stderr, text=True, env=env, cwd=cwd)
    (out, err), close_after, read_end = _child_fds(stdout, stderr)
    args = (module, argv, env, str(cwd), Passed(out), Passed(err), isolate)
    proc = _CONTEXT.Process(target=_run_module, args=args, name=module)
    try:
        proc.start()
    except BaseException:
        if read_end is not None:
            os.close(read_end)
        raise
    finally:
        for fd in close_after:
            os.close(fd)
    out_stream = open(read_end, encoding="utf-8") if read_end is not None else None  # noqa: SIM115
    child = ForkedProcess(proc, [module, *argv], out_stream)
    _LIVE[:] = [p for p in _LIVE if p.poll() is None] + [child]
    return child
