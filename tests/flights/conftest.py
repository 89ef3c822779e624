"""The autopilots a landing flies on: the project's simulated vehicle, and real ArduCopter SITL
when ``SLOPELANDER_ARDUCOPTER`` names a build (``.ci/run`` points it at the shared one)."""

from __future__ import annotations

import os

import pytest

from slopelander_sitl.ardupilot import arducopter_binary
from slopelander_sitl.ardupilot.launch import ArduCopterMissingError

# A flight on real ArduCopter joins the one "arducopter" xdist group (tests/conftest.py): no two
# ArduCopters at once. The flights on the simulated vehicle go where their module says.
# ArduCopter's flights are long: their own time limit.
AUTOPILOTS = [
    "sim",
    pytest.param("ardupilot", marks=[pytest.mark.xdist_group("arducopter"), pytest.mark.timeout(1200)]),
]


def autopilot_available(name: str) -> str:
    """``name``; for ``"ardupilot"`` skipped, saying why, without a binary, and failed when the
    variable names something that is not one."""
    if name == "ardupilot":
        try:
            arducopter_binary()
        except ArduCopterMissingError as exc:
            if os.environ.get("SLOPELANDER_ARDUCOPTER"):
                pytest.fail(str(exc))
            pytest.skip(str(exc))
    return name


@pytest.fixture(params=AUTOPILOTS)
def autopilot(request) -> str:
    """``"sim"`` or ``"ardupilot"``: a vehicle of the test's own."""
    return autopilot_available(request.param)
