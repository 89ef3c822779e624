"""Real ArduCopter SITL behind slopelander's physics, in a loopback-only network namespace.

``start_arducopter`` (:mod:`slopelander_sitl.ardupilot.launch`) is what tests, benchmarks and
``slopelander demo --autopilot ardupilot`` call; ``python -m slopelander_sitl.ardupilot`` is the process it
runs inside the namespace (:mod:`slopelander_sitl.ardupilot.pod`). The binary is the user's own build
(``./waf configure --board sitl && ./waf copter``), found through ``SLOPELANDER_ARDUCOPTER``.
"""

from slopelander_sitl.ardupilot.launch import ArduCopterProcess, arducopter_binary, start_arducopter

__all__ = ["ArduCopterProcess", "arducopter_binary", "start_arducopter"]
