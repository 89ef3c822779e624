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
from slopelander.model.effects import EffectError, UserEffect

_HOOK = "_extra_force = no_extra_force  # USER-EFFECT-HOOK"
_loaded: dict[str, ModuleType] = {}


def cache_dir() -> Path:
    """Where generated kernels live: ``$SLOPELANDER_CACHE_DIR`` or ``~/.cache/slopelander``."""
    root = os.environ.get("SLOPELANDER_CACHE_DIR") or Path.home() / ".cache" / "slopelander"
    return Path(root) / "effects"


def _source_of(effect: UserEffect) -> tuple[str, str, str]:
    """(module name, function name, digest of the module's file) of an effect's force."""
    fn = effect.force.py_func
    mod = sys.modules.get(fn.__module__)
    file = getattr(mod, "__file__", None)
    if mod is None or file is None or fn.__name__ != fn.__qualname__:
        raise EffectError(
            f"user effect {effect.name!r}: its force must be a module-level function of a "
            "Python file (load the file with load_effects)"
        )
    if getattr(mod, fn.__name__, None) is not effect.force:
        raise EffectError(f"user effect {effect.name!r}: {fn.__name__} is not a name in its file")
    digest = hashlib.sha256(Path(file).read_bytes()).hexdigest()
    return fn.__module__, fn.__name__, digest


def kernel_for(effects: Sequence[UserEffect]) -> ModuleType:
    """The integrator module to run for these user effects (the shipped one for none)."""
    if not effects:
        return k
    sources = [_source_of(e) for e in effects]
    h = hashlib.sha256(Path(k.__file__).read_bytes())
    for e, s in zip(effects, sources, strict=True):
        h.update(repr((s, len(e.parameters))).encode())
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


def _generate(effects: Sequence[UserEffect], sources: Sequence[tuple[str, str, str]]) -> str:
    text = Path(k.__file__).read_text()
    if _HOOK not in text:  # pragma: no cover - guards the kernel's own layout
        raise RuntimeError("kernel.py lost its user-effect hook line")
    lines = [f"# user effects: {', '.join(e.name for e in effects)}"]
    calls = []
    offset = 0
    for i, (e, (module, fname, _)) in enumerate(zip(effects, sources, strict=True)):
        n = len(e.parameters)
        lines.append(f"from {module} import {fname} as _user{i}")
        calls.append(f"    _user{i}(t, st, ctx, up[{offset}:{offset + n}], out)")
        offset += n
    lines += ["", "", "@njit(cache=True)", "def _extra_force(t, st, ctx, up, out):", *calls, ""]
    header = "# Generated: the integrator with user effects. Do not edit; delete to rebuild.\n"
    return header + text.replace(_HOOK, "\n".join(lines))


_FILE_LINE = re.compile(r'File "([^"]+)", line (\d+)')


def check_types(effect: UserEffect) -> None:
    """Compile an effect's force for the integrator's argument types; a typing error becomes
    one :class:`EffectError` naming the effect and the line of the user's file."""
    from numba import types
    from numba.core.errors import NumbaError

    arr = types.Array(types.float64, 1, "C")
    fn = effect.force.py_func
    user_file = os.path.abspath(fn.__code__.co_filename)
    try:
        effect.force.compile((types.float64, arr, arr, arr, arr))
    except NumbaError as exc:
        msg = re.sub(r"\x1b\[[0-9;]*m", "", str(exc))
        base = os.path.basename(user_file)
        where = [ln for f, ln in _FILE_LINE.findall(msg) if os.path.basename(f) == base]
        line = where[0] if where else str(fn.__code__.co_firstlineno)
        skip = ("Failed in", "File ", "During", "^", "def ")
        texts = [t.strip() for t in msg.splitlines()]
        first = next((t for t in texts if t and not t.startswith(skip)), type(exc).__name__)
        raise EffectError(
            f"{user_file}:{line}: user effect {effect.name!r} ({fn.__name__}) does not compile: {first}"
        ) from None


@contextmanager
def compiling_notice(what: str = "the model") -> Iterator[None]:
    """Say on stderr that compiling is under way if a first call takes more than a second."""
    timer = threading.Timer(
        1.0,
        lambda: print(
            f"slopelander: compiling {what} (first run after an install or an effect change, "
            "about half a minute; later runs use the cache)...",
            file=sys.stderr,
            flush=True,
        ),
    )
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()
