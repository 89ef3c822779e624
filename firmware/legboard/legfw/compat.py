"""The few names that differ between MicroPython and CPython, in one place."""

try:
    from slopelander.legs import wire  # CPython, in a checkout or an install of slopelander
except ImportError:  # MicroPython: wire.py copied next to the firmware (docs/legs-build.md)
    import wire

try:
    from micropython import const
except ImportError:  # CPython

    def const(x):
        return x


try:
    from time import ticks_add, ticks_diff  # MicroPython: millisecond counters that wrap
except ImportError:  # CPython: a host's counters (SimHal's) do not wrap

    def ticks_add(ticks, delta):
        return ticks + delta

    def ticks_diff(a, b):
        return a - b


__all__ = ["const", "ticks_add", "ticks_diff", "wire"]
