"""Test-wide settings.

Hypothesis runs derandomized by default, so the test command gives the same verdict on every run
and every machine; ``HYPOTHESIS_PROFILE=explore`` draws fresh examples to hunt for new failures.

Why the tests run where and in the order they do (pytest-xdist, ``-n auto --dist loadgroup`` in
pyproject.toml): a test without an ``xdist_group`` mark goes to whichever worker is free. A
module whose tests share a module-scoped fixture (a flying vehicle, a physics server, a fitted
model) carries ``pytestmark = pytest.mark.xdist_group("<module>")``: its tests then run on one
worker in file order, so the fixture is made once and flights that build on each other keep their
order. Every test that flies real ArduCopter SITL is in the one group ``"arducopter"``
(``pytest.mark.xdist_group("arducopter")``), so no two ArduCopters run at once: each is lock-stepped with its
physics only, and two of them starved the companions of a 2-core machine. xdist names a test's
group by joining all its ``xdist_group`` marks, so an ArduCopter test carries that mark alone.
:func:`pytest_collection_modifyitems` fails a test that shares such a fixture outside its users'
one group, saying so.

Each test has a time limit (pytest-timeout, ``timeout`` in pyproject.toml); the long flights
raise theirs with ``pytest.mark.timeout``. The first test that needs the compiled model compiles
it into numba's cache (``.ci/run`` compiles it before pytest, so this costs nothing there).

The simulated vehicles and leg boards a worker starts are forked from a warm
:mod:`multiprocessing` forkserver (:mod:`slopelander_sitl.processes`): ``SLOPELANDER_FORKSERVER=0`` starts
each as a fresh interpreter, as a user's ``slopelander demo`` does."""

from __future__ import annotations

import os

import pytest
from hypothesis import settings

settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))


def pytest_configure(config: pytest.Config) -> None:
    """Inside a parallel worker the identification's evaluations run in that worker alone: a pool
    of one process per core in each of two workers put four busy processes on two cores and
    starved the lock-stepped flights beside them (a fit's search does not depend on it)."""
    if hasattr(config, "workerinput"):
        os.environ.setdefault("SLOPELANDER_WORKERS", "1")
    if os.environ.get("SLOPELANDER_FORKSERVER", "1") != "0":
        from slopelander_sitl import processes

        processes.use_forkserver()


def _group(item: pytest.Item) -> str:
    """The xdist group ``item`` runs in: its ``xdist_group`` marks' names joined, as xdist joins
    them (xdist/remote.py), or "" for none."""
    names = {
        str(m.args[0] if m.args else m.kwargs.get("name", "default"))
        for m in item.iter_markers("xdist_group")
    }
    return "_".join(sorted(names))


def _shared_values(item: pytest.Item) -> list[tuple[str, str, str]]:
    """The fixture values ``item`` uses (directly or through others) that outlive one test: each
    as (fixture name, the node it lives on, its parameter)."""
    defs = getattr(getattr(item, "_fixtureinfo", None), "name2fixturedefs", {})
    callspec = getattr(item, "callspec", None)
    module, _, rest = item.nodeid.partition("::")
    on = {
        "module": module,
        "package": module.rpartition("/")[0],
        "class": module + "::" + rest.rpartition("::")[0],
    }
    return [
        (name, on[fds[-1].scope], repr(callspec.params.get(name)) if callspec else "")
        for name, fds in defs.items()
        if fds and fds[-1].scope in on
    ]


_UNGROUPED = pytest.StashKey[str]()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The tests that share one value of a fixture wider than a test must be in one xdist group:
    otherwise xdist may run them on two workers, each making the fixture again (a second vehicle
    flown, a second fit), and split flights that build on each other. Such a test fails at its
    setup, saying so (:func:`pytest_runtest_setup`)."""
    users: dict[tuple[str, str, str], list[pytest.Item]] = {}
    for item in items:
        for value in _shared_values(item):
            users.setdefault(value, []).append(item)
    for (name, _, _), its in users.items():
        groups = sorted({_group(i) or "no group" for i in its})
        if len(its) > 1 and (len(groups) > 1 or groups == ["no group"]):
            for item in its:
                item.stash[_UNGROUPED] = (
                    f"the tests that share the fixture {name!r} are in {', '.join(groups)}: they must be "
                    "in one xdist_group (pytest.mark.xdist_group; tests/conftest.py says why)"
                )


def _not_in_its_group(item: pytest.Item) -> str | None:
    """Why xdist did not put ``item`` in its group, or None: xdist marks a grouped test by adding
    ``@<group>`` to its id on the worker, and with pytest 9.2 that no longer takes (pytest-xdist
    issue 1386): the tests are then spread as if unmarked, with no error of xdist's own."""
    group = _group(item)
    if not group or not getattr(item.config, "workerinput", None) or not item.config.getvalue("loadgroup"):
        return None
    if item.nodeid.endswith("@" + group):
        return None
    return (
        f"xdist did not put this test in its group {group!r}: pytest {pytest.__version__} with "
        "--dist loadgroup spreads grouped tests (pytest-xdist issue 1386); install the test "
        "extra's pytest (pip install -e '.[test]')"
    )


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    why = item.stash.get(_UNGROUPED, None) or _not_in_its_group(item)
    if why is not None:
        pytest.fail(why, pytrace=False)
