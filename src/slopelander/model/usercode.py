"""A user effect's compiled functions: typed for their seam, mistakes named in one line.

A user's function enters the integrator as a first-class compiled function of its seam's
type (see :mod:`slopelander.model.seams`): no copy of the integrator is made, and the one
compiled integrator is shared by every model. Before that, each function is compiled here for
its seam's argument types, so that a typing error or a wrong return reads as one
:class:`EffectError` naming the effect and the line of the user's file, not numba's pages.
"""

from __future__ import annotations

import os
import re
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from slopelander.model.effects import EffectError, UserEffect

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
        "contact_geometry": (f, arr, arr, arr, i, f),
        "update": (f, arr, arr, arr, f),
    }


def _returns_ok(seam: str, ret) -> bool:
    from numba import types

    if seam in ("force", "point_force", "update"):
        return True
    if seam in ("normal_force", "contact_geometry"):
        return (
            isinstance(ret, types.BaseTuple)
            and len(ret) == (3 if seam == "normal_force" else 2)
            and all(isinstance(r, types.Number) for r in ret)
        )
    return isinstance(ret, types.Number)


_RETURNS = {
    "joint_torque": "a number (the slip torque, N*m)",
    "foot_friction": "a number (the friction coefficient)",
    "normal_force": "a tuple (force N, stiffness N/m, damping N*s/m)",
    "contact_geometry": "a tuple (reach m, along m)",
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
            f"slopelander: compiling {what} (first run after an install or an update, "
            "ten seconds or more; later runs use the cache)...",
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
