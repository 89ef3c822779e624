"""Compile user effects into the integrator, once per change of the user's code.

The integrator calls its user-effect hook as a module global (an argument would be keyed by
the function object's identity, new in every process, so numba's cache would never hit and
would grow on every run). A model with user effects therefore runs a generated copy of
:mod:`slopelander.model.kernel` whose hook calls the users' functions. The copy is written
once to the cache directory under a name that hashes the kernel's source and every user
file's content, so numba's on-disk cache serves it from the second run on, and an edit of
a user file yields a new copy (compiled once).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
import sys
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

from slopelander.model import kernel as k
from slopelander.model.effects import EffectError, UserEffect, check_user_effects
from slopelander.model.layout import layout_digest

_BEGIN = "# USER-EFFECT-HOOKS-BEGIN\n"
_END = "# USER-EFFECT-HOOKS-END\n"
_loaded: dict[str, ModuleType] = {}


def cache_dir() -> Path:
    """Where generated kernels live: ``$SLOPELANDER_CACHE_DIR`` or ``~/.cache/slopelander``."""
    root = os.environ.get("SLOPELANDER_CACHE_DIR") or Path.home() / ".cache" / "slopelander"
    return Path(root) / "effects"


def _source_of(effect: UserEffect, fn) -> tuple[str, str, str]:
    """(module name, function name, digest of the module's file) of one of an effect's functions."""
    py = fn.py_func
    mod = sys.modules.get(py.__module__)
    file = getattr(mod, "__file__", None)
    if mod is None or file is None or py.__name__ != py.__qualname__:
        raise EffectError(
            f"user effect {effect.name!r}: its functions must be module-level functions of a "
            "Python file (load the file with load_effects)"
        )
    if getattr(mod, py.__name__, None) is not fn:
        raise EffectError(f"user effect {effect.name!r}: {py.__name__} is not a name in its file")
    digest = hashlib.sha256(Path(file).read_bytes()).hexdigest()
    return py.__module__, py.__name__, digest


def kernel_for(effects: Sequence[UserEffect]) -> ModuleType:
    """The integrator module to run for these user effects (the shipped one for none)."""
    if not effects:
        return k
    check_user_effects(effects)
    sources = [{seam: _source_of(e, fn) for seam, fn in e.seams().items()} for e in effects]
    h = hashlib.sha256(Path(k.__file__).read_bytes())
    h.update(layout_digest().encode())
    for e, s in zip(effects, sources, strict=True):
        h.update(repr((sorted(s.items()), len(e.parameters))).encode())
    key = h.hexdigest()[:20]
    mod = _loaded.get(key)
    if mod is not None:
        return mod
    name = f"slopelander_kernel_{key}"
    path = cache_dir() / f"{name}.py"
    if not path.is_file():
        for e in effects:
            check_types(e)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(_generate(effects, sources))
        tmp.replace(path)
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    _loaded[key] = mod
    return mod


# seam -> (hook name, its arguments, one effect's call, the hook's return line)
_CALLS = {
    "force": ("_extra_force", "t, st, ctx, up, out", "    {f}(t, st, ctx, {up}, out)", ""),
    "point_force": ("_point_force", "t, st, ctx, up, out", "    {f}(t, st, ctx, {up}, out)", ""),
    "joint_torque": (
        "_joint_torque",
        "t, st, ctx, up, leg, angle, rate, tau",
        "    tau = {f}(t, st, ctx, {up}, leg, angle, rate, tau)",
        "    return tau",
    ),
    "foot_friction": (
        "_foot_friction",
        "t, st, ctx, up, leg, slip_speed, normal_force, mu",
        "    mu = {f}(t, st, ctx, {up}, leg, slip_speed, normal_force, mu)",
        "    return mu",
    ),
    "normal_force": (
        "_normal_force",
        "t, st, ctx, up, point, depth, rate",
        "    n, kk, bb = {f}(t, st, ctx, {up}, point, depth, rate)",
        "    return float(n), float(kk), float(bb)",
    ),
}


def _generate(effects: Sequence[UserEffect], sources: Sequence[dict[str, tuple[str, str, str]]]) -> str:
    """The kernel's source with its hook block binding the users' functions: per seam one
    compiled function calling every effect's function in turn (each on its parameter slice)."""
    text = Path(k.__file__).read_text()
    if _BEGIN not in text or _END not in text:  # pragma: no cover - guards the kernel's own layout
        raise RuntimeError("kernel.py lost its user-effect hook block")
    head, rest = text.split(_BEGIN, 1)
    block, tail = rest.split(_END, 1)
    lines = [f"# user effects: {', '.join(e.name for e in effects)}"]
    bodies: dict[str, list[str]] = {seam: [] for seam in _CALLS}
    offset = 0
    for i, (e, srcs) in enumerate(zip(effects, sources, strict=True)):
        n = len(e.parameters)
        for seam, (module, fname, _) in srcs.items():
            alias = f"_user{i}_{seam}"
            lines.append(f"from {module} import {fname} as {alias}")
            bodies[seam].append(_CALLS[seam][2].format(f=alias, up=f"up[{offset}:{offset + n}]"))
        offset += n
    for seam, (hook, args, _, ret) in _CALLS.items():
        flag = f"HAS_{seam.upper()}"
        if bodies[seam]:
            lines += ["", "", "@njit(cache=True)", f"def {hook}({args}):", *bodies[seam]]
            if ret:
                lines.append(ret)
            lines += ["", "", f"{flag} = True"]
        else:
            default = next(ln for ln in block.splitlines() if ln.startswith(f"{hook} = "))
            lines += [default, f"{flag} = False"]
    header = "# Generated: the integrator with user effects. Do not edit; delete to rebuild.\n"
    return header + head + "\n".join(lines) + "\n" + tail


_FILE_LINE = re.compile(r'File "([^"]+)", line (\d+)')


def _signatures():
    from numba import types

    arr = types.Array(types.float64, 1, "C")
    arr2 = types.Array(types.float64, 2, "C")
    f, i = types.float64, types.int64
    return {
        "force": (f, arr, arr, arr, arr),
        "point_force": (f, arr, arr, arr, arr2),
        "joint_torque": (f, arr, arr, arr, i, f, f, f),
        "foot_friction": (f, arr, arr, arr, i, f, f, f),
        "normal_force": (f, arr, arr, arr, i, f, f),
    }


def _returns_ok(seam: str, ret) -> bool:
    from numba import types

    if seam in ("force", "point_force"):
        return True
    if seam == "normal_force":
        return (
            isinstance(ret, types.BaseTuple)
            and len(ret) == 3
            and all(isinstance(r, types.Number) for r in ret)
        )
    return isinstance(ret, types.Number)


_RETURNS = {
    "joint_torque": "a number (the slip torque, N*m)",
    "foot_friction": "a number (the friction coefficient)",
    "normal_force": "a tuple (force N, stiffness N/m, damping N*s/m)",
}


def check_types(effect: UserEffect) -> None:
    """Compile each of an effect's functions for its seam's argument types; a typing error or
    a wrong return becomes one :class:`EffectError` naming the effect and the line of the
    user's file."""
    from numba.core.errors import NumbaError

    sigs = _signatures()
    for seam, compiled in effect.seams().items():
        fn = compiled.py_func
        user_file = os.path.abspath(fn.__code__.co_filename)
        where = f"{user_file}:{fn.__code__.co_firstlineno}: user effect {effect.name!r} ({fn.__name__})"
        try:
            compiled.compile(sigs[seam])
        except NumbaError as exc:
            msg = re.sub(r"\x1b\[[0-9;]*m", "", str(exc))
            base = os.path.basename(user_file)
            lines = [ln for f, ln in _FILE_LINE.findall(msg) if os.path.basename(f) == base]
            line = lines[0] if lines else str(fn.__code__.co_firstlineno)
            skip = ("Failed in", "File ", "During", "^", "def ")
            texts = [t.strip() for t in msg.splitlines()]
            first = next((t for t in texts if t and not t.startswith(skip)), type(exc).__name__)
            raise EffectError(
                f"{user_file}:{line}: user effect {effect.name!r} ({fn.__name__}) does not compile: {first}"
            ) from None
        ret = next(sg.return_type for sg in compiled.nopython_signatures if tuple(sg.args) == sigs[seam])
        if not _returns_ok(seam, ret):
            raise EffectError(f"{where}: as its {seam} it must return {_RETURNS[seam]}, not {ret}")


@contextmanager
def compiling_notice(
    what: str = "the model", dispatcher: object = None, after: float = 3.0
) -> Iterator[None]:
    """Say on stderr that compiling is under way once numba has been compiling for ``after`` s.

    Only a real compilation counts (numba's ``numba:compile`` event, which a cache hit does not
    raise): loading the cached code can take a few seconds on a busy machine, and a slow start
    is then not announced as a half-minute compile. With ``dispatcher`` (a numba function), say
    nothing once it holds compiled code: a long batch of landings is work, not compiling.
    """
    if getattr(dispatcher, "signatures", None):
        yield
        return
    from numba.core import event

    lock = threading.Lock()
    state = {"depth": 0, "said": False, "timer": None}

    def say() -> None:
        with lock:
            state["timer"] = None
            if state["said"] or state["depth"] <= 0:
                return  # the compile it was armed for is over: the next one arms it again
            state["said"] = True
        print(
            f"slopelander: compiling {what} (first run after an install or an effect change, "
            "about half a minute; later runs use the cache)...",
            file=sys.stderr,
            flush=True,
        )

    class Compiles(event.Listener):
        def on_start(self, ev: object) -> None:
            with lock:
                state["depth"] += 1
                if state["said"] or state["timer"] is not None:
                    return
                timer = threading.Timer(after, say)
                timer.daemon = True
                state["timer"] = timer
            timer.start()

        def on_end(self, ev: object) -> None:
            with lock:
                state["depth"] -= 1

    try:
        with event.install_listener("numba:compile", Compiles()):
            yield
    finally:
        with lock:
            state["said"] = True  # nothing more after the block
            timer = state["timer"]
        if timer is not None:
            timer.cancel()
