"""Simulators forked from one warm process instead of started cold.

Starting ``python -m slopelander_sitl.vehicle`` costs about 2 s of CPU before its first tick: the imports
(numba, pymavlink's dialect, lupa) and the compiled model loaded from numba's cache. A test run
starts a vehicle and a leg board for every landing, a few hundred of them. The zygote is one
process that has paid this once: asked for ``python -m MODULE ARGS``, it forks, and the child runs
the module as ``__main__`` with the caller's arguments, environment, working directory, stdout and
stderr, exactly as a fresh interpreter would run it from there. The caller gets a
:class:`ZygoteProcess`, which answers as :class:`subprocess.Popen` does (pid, stdout, poll, wait,
terminate, kill, returncode).

The zygote ends when the program that started it ends, and takes its children with it
(:mod:`slopelander_sitl.parent_watch`'s rule: it watches its parent from its loop, without a thread, as a
process that forks should). A child watches the zygote, its real parent.

Used where many simulators are started by one process: the test suite turns it on
(``tests/conftest.py``); a demo or a user's command starts its one simulator the ordinary way.
What a zygote's child starts in turn is forked from that child, whose modules are loaded too:
ArduCopter's pod (``slopelander_sitl.ardupilot``, moved into its own loopback-only network namespace as it is
forked) forks its JSON physics so.

    python -m slopelander_sitl.zygote --socket PATH [--preload MODULE ...]
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import importlib
import json
import os
import runpy
import select
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from pathlib import Path
from typing import IO

from slopelander_sitl.parent_watch import ENV, GRACE_S, PERIOD_S

#: modules a test run forks simulators of; each may define ``warm()``, run once in the zygote
PRELOAD = (
    "slopelander_sitl.vehicle.__main__",
    "slopelander_sitl.legboard.__main__",
    "slopelander_sitl.json_physics.__main__",
    "slopelander_sitl.ardupilot.pod",
)
MAX_MESSAGE = 1 << 20
START_TIMEOUT_S = 900.0
"""How long a zygote may take to say it is ready (its warm-up may compile the model)."""


# -- the caller's side ------------------------------------------------------------------------
class _Forked:
    """What :class:`subprocess.Popen` offers that the launchers use, for a forked child; a
    subclass says how its exit status is learnt (``_read_status``)."""

    args: list[str]
    pid: int
    stdout: IO[str] | None
    returncode: int | None

    def _read_status(self, timeout: float | None) -> bool:
        raise NotImplementedError

    def poll(self) -> int | None:
        if self.returncode is None:
            self._read_status(0.0)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        if self.returncode is None and not self._read_status(timeout):
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
        assert self.returncode is not None
        return self.returncode

    def communicate(self, timeout: float | None = None) -> tuple[str, None]:
        """Wait for the end, then the rest of its stdout (a simulator says little there: its
        ready line and its summary)."""
        self.wait(timeout)
        out = self.stdout.read() if self.stdout is not None else ""
        return out, None

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


class ZygoteProcess(_Forked):
    """A child of the zygote, answering as :class:`subprocess.Popen` does. Its exit status comes
    from the zygote, which reaps it."""

    def __init__(self, args: list[str], pid: int, conn: socket.socket, stdout: IO[str] | None) -> None:
        self.args, self.pid, self._conn, self.stdout = args, pid, conn, stdout
        self.returncode: int | None = None
        #: the preloaded modules the zygote had warmed when it forked this child
        self.warm: tuple[str, ...] = ()

    def _read_status(self, timeout: float | None) -> bool:
        ready, _, _ = select.select([self._conn], [], [], timeout)
        if not ready:
            return False
        data = self._conn.recv(4096)
        if data:
            self.returncode = int(json.loads(data)["exit"])
        else:  # the zygote went away without telling: the child ends with it (parent watch)
            while _alive(self.pid):
                time.sleep(0.05)
            self.returncode = -signal.SIGKILL
        self._conn.close()
        return True


class ForkedProcess(_Forked):
    """A child forked from this process (:func:`fork_here`), which reaps it itself."""

    def __init__(self, args: list[str], pid: int, stdout: IO[str] | None) -> None:
        self.args, self.pid, self.stdout = args, pid, stdout
        self.returncode: int | None = None

    def _read_status(self, timeout: float | None) -> bool:
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
                return True
            if end is not None and time.monotonic() >= end:
                return False
            time.sleep(0.01)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class Zygote:
    """The caller's handle on its zygote process (started on first use, restarted if it died)."""

    def __init__(self, preload: tuple[str, ...] = PRELOAD) -> None:
        self.preload = preload
        self._proc: subprocess.Popen | None = None
        self._dir: tempfile.TemporaryDirectory | None = None
        self._lock = threading.Lock()

    @property
    def socket_path(self) -> Path:
        assert self._dir is not None
        return Path(self._dir.name) / "zygote.sock"

    def _ensure(self) -> None:
        if self._proc is not None and self._proc.poll() is None:
            return
        from slopelander_sitl.vehicle.launch import REPO, child_env

        self.close()
        self._dir = tempfile.TemporaryDirectory(prefix="sl-zygote-")
        cmd = [
            sys.executable,
            "-m",
            "slopelander_sitl.zygote",
            "--socket",
            str(self.socket_path),
            "--preload",
            *self.preload,
        ]
        self._proc = subprocess.Popen(
            cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, text=True, env=child_env(), cwd=REPO
        )
        # a fresh checkout compiles the model here first (a minute or more on a loaded machine)
        ready, _, _ = select.select([self._proc.stdout], [], [], START_TIMEOUT_S)
        line = self._proc.stdout.readline() if ready else ""
        if not line.startswith("zygote ready"):
            self._proc.kill()
            self._proc.wait()
            raise RuntimeError("the simulators' zygote did not start (run its command to see why)")

    def spawn(
        self,
        module: str,
        argv: list[str],
        *,
        env: dict[str, str],
        cwd: Path | str,
        stdout: int | IO | None = None,
        stderr: int | IO | None = None,
        isolate: bool = False,
    ) -> ZygoteProcess:
        """``python -m module *argv`` forked from the zygote. ``stdout``/``stderr``:
        ``subprocess.PIPE`` (stdout only, read as text), ``subprocess.DEVNULL``, an open file,
        or None (the caller's own). ``isolate``: the child first moves into a loopback-only
        network namespace of its own (:func:`slopelander_sitl.netns.enter_isolated`)."""
        with self._lock:
            self._ensure()
            conn = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
            conn.connect(str(self.socket_path))
        fds, close_after, read_end = _child_fds(stdout, stderr)
        try:
            req = _request(module, argv, env, cwd, isolate)
            socket.send_fds(conn, [json.dumps(req).encode()], fds)
            reply = json.loads(conn.recv(4096))
            pid = int(reply["pid"])
        except (OSError, ValueError, KeyError) as exc:
            conn.close()
            if read_end is not None:
                os.close(read_end)
            raise RuntimeError(f"the simulators' zygote could not start {module}: {exc}") from None
        finally:
            for fd in close_after:
                os.close(fd)
        out = open(read_end, encoding="utf-8") if read_end is not None else None  # noqa: SIM115
        child = ZygoteProcess([module, *argv], pid, conn, out)
        child.warm = tuple(reply.get("warm", ()))
        return child

    def close(self) -> None:
        if self._proc is not None:
            if self._proc.poll() is None:
                self._proc.terminate()
                try:
                    self._proc.wait(GRACE_S + 5.0)
                except subprocess.TimeoutExpired:
                    self._proc.kill()
                    self._proc.wait()
            self._proc = None
        if self._dir is not None:
            self._dir.cleanup()
            self._dir = None


_ZYGOTE: Zygote | None = None
_WARM = False
"""True in a child of a zygote: its modules are loaded already, so what it starts is forked from
it (:func:`start`)."""


def enable(preload: tuple[str, ...] = PRELOAD) -> None:
    """Start this process's simulators from a zygote from now on (not its children's)."""
    global _ZYGOTE
    if _ZYGOTE is None:
        _ZYGOTE = Zygote(preload)
        atexit.register(_ZYGOTE.close)


def active() -> Zygote | None:
    return _ZYGOTE


def _request(module: str, argv: list[str], env: dict[str, str], cwd: Path | str, isolate: bool) -> dict:
    """What a forked child runs (:func:`_run_child`), from the zygote or from this process."""
    return {"module": module, "argv": argv, "env": env, "cwd": str(cwd), "isolate": isolate}


def _child_fds(stdout: int | IO | None, stderr: int | IO | None) -> tuple[list[int], list[int], int | None]:
    """The descriptors a child gets as stdout and stderr, those to close here once it has them,
    and the read end of its stdout pipe (``subprocess.PIPE``) if any."""
    close_after: list[int] = []
    read_end = None

    def fd_for(target: int | IO | None, default: int) -> int:
        nonlocal read_end
        if target is None:
            return default
        if target == subprocess.PIPE:
            r, w = os.pipe()
            read_end = r
            close_after.append(w)
            return w
        if target == subprocess.DEVNULL:
            fd = os.open(os.devnull, os.O_RDWR)
            close_after.append(fd)
            return fd
        return target.fileno()

    return [fd_for(stdout, 1), fd_for(stderr, 2)], close_after, read_end


def fork_here(
    module: str,
    argv: list[str],
    *,
    env: dict[str, str],
    cwd: Path | str,
    stdout: int | IO | None = None,
    stderr: int | IO | None = None,
    isolate: bool = False,
) -> ForkedProcess:
    """``python -m module *argv`` forked from this process, as the zygote forks it (the same
    arguments). Forks: call it before this process starts a thread."""
    fds, close_after, read_end = _child_fds(stdout, stderr)
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        pid = os.fork()
    except OSError:
        for fd in close_after + ([read_end] if read_end is not None else []):
            os.close(fd)
        raise
    if pid == 0:
        _run_child(_request(module, argv, env, cwd, isolate), fds, [read_end] if read_end is not None else [])
    for fd in close_after:
        os.close(fd)
    out = open(read_end, encoding="utf-8") if read_end is not None else None  # noqa: SIM115
    return ForkedProcess([module, *argv], pid, out)


def start(
    module: str,
    argv: list[str],
    *,
    env: dict[str, str],
    cwd: Path | str,
    stdout: int | IO | None = None,
    stderr: int | IO | None = None,
    isolate: bool = False,
) -> subprocess.Popen | ZygoteProcess | ForkedProcess:
    """``python -m module *argv`` as text streams: forked from the zygote when :func:`enable`\\ d,
    forked from this process when it is itself a zygote's child (what it starts, such as
    ArduCopter's physics from its pod, finds its modules loaded), else a fresh interpreter.
    ``isolate``: run it in a loopback-only network namespace of its own (:mod:`slopelander_sitl.netns`)."""
    if _ZYGOTE is not None:
        return _ZYGOTE.spawn(module, argv, env=env, cwd=cwd, stdout=stdout, stderr=stderr, isolate=isolate)
    if _WARM:
        return fork_here(module, argv, env=env, cwd=cwd, stdout=stdout, stderr=stderr, isolate=isolate)
    cmd = [sys.executable, "-m", module, *argv]
    if isolate:
        from slopelander_sitl.netns import isolated_command

        cmd = isolated_command(cmd)
    return subprocess.Popen(cmd, stdout=stdout, stderr=stderr, text=True, env=env, cwd=cwd)


# -- the zygote itself ------------------------------------------------------------------------
def _run_child(req: dict, fds: list[int], keep_closed: list[int]) -> None:
    """In the forked child: become ``python -m module argv`` and never return."""
    code = 1
    try:
        # the module the child's code imports: in the zygote this file runs as __main__
        importlib.import_module("slopelander_sitl.zygote")._WARM = True
        signal.set_wakeup_fd(-1)
        for sig in (signal.SIGCHLD, signal.SIGTERM):
            signal.signal(sig, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        for fd in keep_closed:
            with contextlib.suppress(OSError):
                os.close(fd)
        os.dup2(fds[0], 1)
        os.dup2(fds[1], 2)
        for fd in fds:
            if fd > 2:
                os.close(fd)
        os.chdir(req["cwd"])
        env = dict(req["env"])
        if ENV in env:
            env[ENV] = str(os.getppid())  # the process it was forked from: it watches that
        os.environ.clear()
        os.environ.update(env)
        sys.argv = [req["module"], *req["argv"]]
        if req.get("isolate"):
            from slopelander_sitl.netns import NamespaceError, enter_isolated

            try:
                enter_isolated()
            except NamespaceError as exc:
                print(f"{req['module']}: error: {exc}", file=sys.stderr)
                code = 2
                return
        try:
            runpy.run_module(req["module"], run_name="__main__", alter_sys=True)
            code = 0
        except SystemExit as exc:
            if exc.code is None:
                code = 0
            elif isinstance(exc.code, int):
                code = exc.code
            else:
                print(exc.code, file=sys.stderr)
                code = 1
        except KeyboardInterrupt:
            code = 128 + signal.SIGINT
        except BaseException:
            traceback.print_exc()
            code = 1
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(code)


#: simulators that need no compiled model: a zygote asked only for these never loads it
LIGHT = ("slopelander_sitl.legboard",)


def _warm(modules: list[object]) -> None:
    for mod in modules:
        warm = getattr(mod, "warm", None)
        if warm is not None:
            warm()


def serve(path: str, preload: list[str]) -> int:
    """Import ``preload``, then fork what is asked for. The light modules (:data:`LIGHT`) are
    warmed at once; the others, which load the compiled model, before the first request for
    anything else: a test run starts leg boards while the model still compiles (the tests that
    need no model run first, tests/compile_once.py), and a zygote that loaded the model then
    compiled it a second time beside the compile."""
    loaded = [importlib.import_module(name) for name in preload]
    light = [m for m in loaded if m.__name__.removesuffix(".__main__") in LIGHT]
    _warm(light)
    warmed = [m.__name__ for m in light]  # told to each caller with its child's pid
    heavy = [m for m in loaded if m not in light]
    try:
        expected = int(os.environ.get(ENV, ""))
    except ValueError:
        expected = None
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    listener.bind(path)
    listener.listen(64)
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_r, False)
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)
    running = [True]

    def stop(signum: int, frame: object) -> None:
        running[0] = False

    signal.signal(signal.SIGCHLD, lambda signum, frame: None)
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    children: dict[int, socket.socket] = {}
    print("zygote ready", flush=True)

    def reap() -> None:
        while children:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            conn = children.pop(pid, None)
            if conn is not None:
                with contextlib.suppress(OSError):
                    conn.send(json.dumps({"exit": os.waitstatus_to_exitcode(status)}).encode())
                conn.close()

    while running[0]:
        if expected is not None and os.getppid() != expected:
            break  # the program that started this zygote is gone
        try:
            ready, _, _ = select.select([listener, wake_r], [], [], PERIOD_S)
        except InterruptedError:
            ready = []
        if wake_r in ready:
            try:
                while os.read(wake_r, 512):
                    pass
            except BlockingIOError:
                pass
        reap()
        if listener not in ready:
            continue
        conn, _ = listener.accept()
        try:
            msg, fds, _, _ = socket.recv_fds(conn, MAX_MESSAGE, 2)
            req = json.loads(msg)
        except (OSError, ValueError):
            conn.close()
            continue
        if heavy and req.get("module") not in LIGHT:
            try:
                _warm(heavy)
                warmed += [m.__name__ for m in heavy]
            except Exception:  # each child then loads what it needs, and says what fails
                traceback.print_exc()
            heavy = []
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            others = [conn.fileno(), *(c.fileno() for c in children.values())]
            _run_child(req, fds, [listener.fileno(), wake_r, wake_w, *others])
        for fd in fds:
            os.close(fd)
        with contextlib.suppress(OSError):
            conn.send(json.dumps({"pid": pid, "warm": warmed}).encode())
        children[pid] = conn
    # stopping: the children first, then this process
    for pid in list(children):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGTERM)
    end = time.monotonic() + GRACE_S
    while children and time.monotonic() < end:
        reap()
        time.sleep(0.05)
    for pid in list(children):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    while children:
        reap()
        time.sleep(0.01)
    listener.close()
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m slopelander_sitl.zygote", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--socket", required=True, help="the Unix socket to listen on")
    ap.add_argument("--preload", nargs="*", default=list(PRELOAD), help="modules to import (and warm) first")
    a = ap.parse_args(argv)
    return serve(a.socket, a.preload)


if __name__ == "__main__":
    sys.exit(main())
