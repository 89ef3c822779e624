"""A loopback-only network namespace for ArduPilot's SITL.

ArduCopter SITL listens for MAVLink on TCP 5760/5762/5763 on every interface. Run where other
networks are reachable, it would serve them; so every ArduCopter this project starts runs inside a
new network namespace that holds only ``lo`` (``unshare -rn``: a new user namespace mapping this
user to root in it, so no privilege is needed, and a new network namespace). What talks to it
from outside crosses through UNIX sockets in its working folder (:mod:`slopelander_sitl.bridge`): files, not
network addresses.
"""

from __future__ import annotations

import ctypes
import fcntl
import os
import shutil
import socket
import struct
from pathlib import Path

from slopelander.errors import SlopelanderError

_SIOCGIFFLAGS, _SIOCSIFFLAGS, _IFF_UP = 0x8913, 0x8914, 0x1
_CLONE_NEWUSER, _CLONE_NEWNET = 0x10000000, 0x40000000
_IFREQ = "16sH22x"  # struct ifreq: name, flags, padding to its 40 bytes


class NamespaceError(SlopelanderError):
    """A loopback-only network namespace could not be made or is not loopback-only."""


def isolated_command(argv: list[str]) -> list[str]:
    """``argv`` run in a new user and network namespace (``unshare -rn``)."""
    unshare = shutil.which("unshare")
    if unshare is None:
        raise NamespaceError(
            "`unshare` (util-linux) is not installed: ArduCopter SITL is only run inside a "
            "loopback-only network namespace"
        )
    return [unshare, "--user", "--map-root-user", "--net", *argv]


def enter_isolated() -> None:
    """Move this process into a new user and network namespace, as ``unshare --user
    --map-root-user --net`` moves the command it runs (this user mapped to root in the new user
    namespace, ``setgroups`` denied first, as the kernel requires of an unprivileged map: see
    user_namespaces(7)). For a process forked from a warm one (:mod:`slopelander_sitl.processes`), which
    has no
    ``unshare`` to exec: the kernel refuses a new user namespace to a process with more than one
    thread, so call it before any thread starts. Raises :class:`NamespaceError` if it cannot."""
    uid, gid = os.geteuid(), os.getegid()
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.unshare(_CLONE_NEWUSER | _CLONE_NEWNET) != 0:
        err = ctypes.get_errno()
        raise NamespaceError(f"cannot make a loopback-only network namespace: unshare: {os.strerror(err)}")
    try:
        Path("/proc/self/setgroups").write_text("deny")
        Path("/proc/self/uid_map").write_text(f"0 {uid} 1")
        Path("/proc/self/gid_map").write_text(f"0 {gid} 1")
    except OSError as exc:
        raise NamespaceError(f"cannot map this user into its new namespace: {exc}") from None


def bring_loopback_up() -> None:
    """Inside a new network namespace: bring ``lo`` up and check that it is the only interface.
    Raises :class:`NamespaceError` otherwise (this process is not isolated)."""
    names = sorted(name for _, name in socket.if_nameindex())
    if names != ["lo"]:
        raise NamespaceError(f"not a loopback-only network namespace: interfaces {', '.join(names)}")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        req = struct.pack(_IFREQ, b"lo", 0)
        flags = struct.unpack(_IFREQ, fcntl.ioctl(s, _SIOCGIFFLAGS, req))[1]
        fcntl.ioctl(s, _SIOCSIFFLAGS, struct.pack(_IFREQ, b"lo", flags | _IFF_UP))
