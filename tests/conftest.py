"""Test-wide settings.

Hypothesis runs derandomized by default, so the test command gives the same verdict on every run
and every machine; ``HYPOTHESIS_PROFILE=explore`` draws fresh examples to hunt for new failures.

The suite runs on parallel workers (pytest-xdist, ``-n auto --dist loadgroup`` in pyproject.toml).
Each test module is one work unit, run on one worker in file order, so a module-scoped fixture (a
flying vehicle, a physics server) is made once and the flight tests that share one vehicle keep
their order. A module marked ``spread`` shares nothing wider than a test: its tests go to
whichever worker is free (the landings on both autopilots, each on its own vehicle)."""

from __future__ import annotations

import os

import pytest
from hypothesis import settings

settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))


def work_unit(item: pytest.Item) -> str | None:
    """The xdist group of a test: its module's path, or None for a test of a ``spread`` module;
    every test marked ``arducopter`` (it flies real ArduCopter SITL) in one group, so no two
    ArduCopters run at once: each is lock-stepped with its physics only, not with the companion,
    and two of them starved the companions of a 2-core machine (boards judged silent, reflexes
    lapsed)."""
    if item.get_closest_marker("arducopter") is not None:
        return "arducopter"
    if item.get_closest_marker("spread") is not None:
        return None
    return item.nodeid.split("::", 1)[0]


@pytest.hookimpl(tryfirst=True)  # before xdist's worker reads the groups into the test ids
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        group = work_unit(item)
        if group is not None:
            item.add_marker(pytest.mark.xdist_group(group))
