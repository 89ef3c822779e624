"""A MAVLink link that fails on purpose: a relay between the companion and the vehicle that drops,
delays, duplicates, reorders and corrupts whole MAVLink frames and cuts the link on command.

Run it as a process (``python -m slopelander_sitl.linkfault --listen tcp:127.0.0.1:5770 --to
tcp:127.0.0.1:5760 --drop 0.05``) and steer it at run time through its control port
(:class:`RelayControl`), so a test can cut the link in exactly the landing state it wants.
"""

from slopelander_sitl.linkfault.faults import LinkFaults
from slopelander_sitl.linkfault.relay import Relay, RelayControl

__all__ = ["LinkFaults", "Relay", "RelayControl"]
