"""CPython's stand-in for MicroPython's ``micropython`` module (tests only: on MicroPython the
built-in one is used): what the reference board's HAL and the firmware call of it."""


def const(x):
    return x


def kbd_intr(ch):
    return None
