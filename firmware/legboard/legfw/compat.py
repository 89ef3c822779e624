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


__all__ = ["const", "wire"]
