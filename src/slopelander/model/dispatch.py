"""Calling a compiled integrator without numba's per-call type inference.

numba types every argument of every call to pick the compiled overload. For the seam table
(nested tuples of first-class functions) that costs about 2.7 ms, half of a whole landing: an
identification run of 15,000 landings spent 40 s of its 146 s typing arguments. The types of
the arguments the integrator receives follow from a few cheap Python facts (array dtype,
dimensions, layout; a law's seam), so the overload is looked up once per such key and called
directly afterwards.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

_ENTRIES: dict[tuple, Callable[..., Any]] = {}
_TUPLES: dict[int, tuple[tuple, object]] = {}
"""Keys of tuples of no arrays seen before (a model's seam laws are passed on every call), by
identity; the tuple is kept so that its id is not reused. A tuple holding an array is not kept:
the array's flags can change, and a call's arguments would keep its arrays alive."""
_TUPLES_MAX = 4096


def _key(a: object) -> object:
    """What numba's type of ``a`` depends on, computed without numba."""
    if isinstance(a, np.ndarray):
        f = a.flags
        return ("a", a.dtype.str, a.ndim, f.c_contiguous, f.f_contiguous, f.writeable, f.aligned)
    if isinstance(a, tuple):
        hit = _TUPLES.get(id(a))
        if hit is not None and hit[0] is a:
            return hit[1]
        key = ("t", *(_key(x) for x in a))
        if len(_TUPLES) < _TUPLES_MAX and not _has_array(key):
            _TUPLES[id(a)] = (a, key)
        return key
    seam = getattr(a, "seam", None)
    if seam is not None:
        return ("law", seam)  # a seam law's type is the seam's signature, whatever the function
    return type(a)


def _has_array(key: object) -> bool:
    return isinstance(key, tuple) and (key[0] == "a" or any(_has_array(k) for k in key[1:]))


def call(dispatcher: Any, *args: object) -> Any:
    """``dispatcher(*args)``, through the overload already compiled for these argument types.

    The first call with a new key goes through numba (compiling if need be); later calls go
    straight to the compiled entry point.
    """
    key = (id(dispatcher), _key(args))
    entry = _ENTRIES.get(key)
    if entry is not None:
        return entry(*args)
    out = dispatcher(*args)
    sig = tuple(dispatcher.typeof_pyval(a) for a in args)
    cres = dispatcher.overloads.get(sig)
    if cres is not None:
        _ENTRIES[key] = cres.entry_point
    return out


def entry(dispatcher: Any, *args: object) -> Callable[..., Any] | None:
    """The compiled entry point :func:`call` uses for these argument types, once a call has
    found it (None before): for a caller that passes arguments of the same types on every call
    (the stepper's 1200 steps a simulated second) and can skip even the key."""
    return _ENTRIES.get((id(dispatcher), _key(args)))
