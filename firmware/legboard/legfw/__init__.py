"""Leg-board firmware (MicroPython; also runs on CPython for the simulated board).

``config`` the board's settings, ``leg`` one leg's controller, ``board`` the protocol and the
scheduler, ``hal`` what the firmware needs of the hardware; ``rp2040`` that for the reference
board, ``simhal`` and ``plant`` for a host, ``host`` the host's main loop.
"""

FIRMWARE_VERSION = 0x0100  # 1.0, reported in HELLO_REPLY
