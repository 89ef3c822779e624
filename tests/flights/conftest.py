"""The autopilots a landing flies on: the project's simulated vehicle, and real ArduCopter SITL
when ``SLOPELANDER_ARDUCOPTER`` names a build (``.ci/run`` points it at the shared one)."""

from __future__ import annotations

import os

import pytest

from sitl.ardupilot import arducopter_binary
from sitl.ardupilot.launch import ArduCopterMissingError

# A flight on real ArduCopter joins the one "arducopter" work unit (tests/conftest.py): no two
# ArduCopters at once. A flight on the simulated vehicle goes to whichever worker is free.
AUTOPILOTS = ["sim", pytest.param("ardupilot", marks=pytest.mark.arducopter)]


@pytest.fixture(params=AUTOPILOTS)
def autopilot(request) -> str:
    """``"sim"``, or ``"ardupilot"`` (skipped, saying why, without a binary; failed when the
    variable names something that is not one)."""
    if request.param == "ardupilot":
        try:
            arducopter_binary()
        except ArduCopterMissingError as exc:
            if os.environ.get("SLOPELANDER_ARDUCOPTER"):
                pytest.fail(str(exc))
            pytest.skip(str(exc))
    return request.param
