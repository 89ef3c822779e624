"""Test-wide settings.

Hypothesis runs derandomized by default, so the test command gives the same verdict on every run
and every machine; ``HYPOTHESIS_PROFILE=explore`` draws fresh examples to hunt for new failures.

The suite runs on parallel workers (pytest-xdist, ``-n auto --dist loadgroup`` in pyproject.toml).
Each test module is one work unit, run on one worker in file order, so a module-scoped fixture (a
flying vehicle, a physics server) is made once and the flight tests that share one vehicle keep
their order; the tests that use a module-scoped fixture some of the module's tests do not use go
after those others (:func:`shared_fixtures_last`), so it ends with its last user. A module
marked ``spread`` shares nothing wider than a test: its tests go to whichever worker is free.

The work units are handed out in the order :func:`work_order` makes (``--no-loadscope-reorder``
keeps it; xdist's own order is by number of tests, which put the few long flights last and left
one worker idle for the last ten minutes): a unit's length is the sum of its tests' times in
``tests/durations.json``, its CPU the sum of theirs in ``tests/cpu_seconds.json`` (each test's
process tree), both written from a measured run by ``benchmarks/suite_time.py``; a test not in
them counts ``UNKNOWN_TEST_S`` and one core. First come the units marked ``model_free``, which
run while the model compiles on the other core (tests/compile_once.py)."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import settings

settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))


#: where the background compile leaves its flag (tests/compile_once.py), for every worker
MODEL_READY = "SLOPELANDER_MODEL_READY"
_model_ok = False


@pytest.fixture(scope="module", autouse=True)
def _model_compiled(request: pytest.FixtureRequest) -> None:
    """A module waits for the model's compile, unless it is marked ``model_free``; if the model
    does not compile, each of its tests fails saying why. Module-scoped, so that it comes before
    the module's own fixtures (a flying vehicle loads the model)."""
    global _model_ok
    flag = os.environ.get(MODEL_READY)
    if _model_ok or not flag or request.node.get_closest_marker("model_free") is not None:
        return
    from tests.compile_once import wait_for_model

    why = wait_for_model(Path(flag))
    if why is not None:
        pytest.fail(why, pytrace=False)
    _model_ok = True


def pytest_configure(config: pytest.Config) -> None:
    """Inside a parallel worker the identification's evaluations run in that worker alone: a pool
    of one process per core in each of two workers put four busy processes on two cores and
    starved the lock-stepped flights beside them (a fit's search does not depend on it)."""
    if hasattr(config, "workerinput"):
        os.environ.setdefault("SLOPELANDER_WORKERS", "1")
    elif config.option.collectonly or os.environ.get("SLOPELANDER_COMPILE_ONCE", "1") == "0":
        # the suite's own checks of its settings run pytest on toy modules that need no model,
        # with SLOPELANDER_COMPILE_ONCE=0
        os.environ.pop(MODEL_READY, None)
    else:
        # one process compiles the model (tests/compile_once.py) while the workers start and run
        # the tests that need none; they see the flag's path in their environment
        from tests.compile_once import BackgroundCompile

        flag = Path(tempfile.mkdtemp(prefix="sl-compile-")) / "done"
        os.environ[MODEL_READY] = str(flag)
        config._slopelander_compile = BackgroundCompile(flag)
    if os.environ.get("SLOPELANDER_ZYGOTE", "1") != "0":
        # the simulated vehicles and leg boards this process starts (one of each a landing) are
        # forked from one warm process: about 2 s of CPU each for imports and the compiled model
        # otherwise (src/slopelander_sitl/zygote.py; SLOPELANDER_ZYGOTE=0 starts each fresh, as a user's does)
        from slopelander_sitl import zygote

        zygote.enable()


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


DURATIONS = Path(__file__).with_name("durations.json")
CPU_SECONDS = Path(__file__).with_name("cpu_seconds.json")
UNKNOWN_TEST_S = 2.0
#: cores a unit's processes keep busy, on average over its wall time, below which it is "light":
#: measured in a run of two workers, where a test bound by its CPU shares the cores (the
#: identification read 0.75 and ArduCopter's unit 0.95 at 22:04), while the tests that wait on the
#: wall clock read 0.04-0.59
LIGHT_CORES = 0.6


def collection_id(nodeid: str) -> str:
    """A test's id as collected: without the ``@group`` xdist appends in its workers (after this
    file's hooks have ordered the items), so recorded times match the items they order."""
    head, at, group = nodeid.rpartition("@")
    if at and "::" in head and "::" not in group and "]" not in group:
        return head
    return nodeid


def recorded_durations(path: Path = DURATIONS) -> dict[str, float]:
    """Test id -> seconds (of wall time, or of CPU from ``CPU_SECONDS``) from a measured run; empty
    when the file is missing or unreadable (every test then counts the same, units with more tests
    go first: xdist's own rule; the order changes the run's length, never its result)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    return {collection_id(k): float(v) for k, v in data.items() if isinstance(v, (int, float))}


def work_order(
    items: list[pytest.Item], seconds: dict[str, float], cpu: dict[str, float] | None = None
) -> list[pytest.Item]:
    """The items reordered by work unit, each unit's tests kept in their order (a unit's first
    appearance breaks ties, so the order is the same on every worker): the units that need no
    model (every test marked ``model_free``) first, while the model compiles
    (tests/compile_once.py); then the others, longest first. With each test's CPU recorded
    (``cpu``), the light units (their processes busy fewer than ``LIGHT_CORES`` cores over their
    wall time: flights on the wall clock, MAVProxy's start, commands that wait) and the others
    are each taken longest first and merged so that each kind's share of its own total runs
    level along the queue: the two workers take units from it as they free up, so one mostly
    runs a light unit while the other runs a heavy one. Handed out by length alone, the light
    units had come last, side by side, and left a core idle for several minutes (2026-11-27:
    1.44-1.63 of 2 cores busy in minutes 11-15 of the 21:41 run; ``suite_time.py`` names the
    tests of such minutes)."""
    units: dict[str, list[pytest.Item]] = {}
    for item in items:
        units.setdefault(work_unit(item) or item.nodeid, []).append(item)
    cost = {u: sum(seconds.get(i.nodeid, UNKNOWN_TEST_S) for i in its) for u, its in units.items()}
    free = {u: all(i.get_closest_marker("model_free") is not None for i in its) for u, its in units.items()}
    rank = {u: n for n, u in enumerate(units)}
    by_length = sorted(units, key=lambda u: (not free[u], -cost[u], rank[u]))
    if not cpu:
        return [item for u in by_length for item in units[u]]
    cores = {
        u: sum(cpu.get(i.nodeid, seconds.get(i.nodeid, UNKNOWN_TEST_S)) for i in its) / max(cost[u], 1e-9)
        for u, its in units.items()
    }
    first = [u for u in by_length if free[u]]
    light = [u for u in by_length if not free[u] and cores[u] < LIGHT_CORES]
    heavy = [u for u in by_length if not free[u] and cores[u] >= LIGHT_CORES]
    total_l, total_h = sum(cost[u] for u in light) or 1.0, sum(cost[u] for u in heavy) or 1.0
    merged, done_l, done_h = [], 0.0, 0.0
    while light or heavy:
        if heavy and (not light or done_h / total_h <= done_l / total_l):
            u = heavy.pop(0)
            done_h += cost[u]
        else:
            u = light.pop(0)
            done_l += cost[u]
        merged.append(u)
    return [item for u in first + merged for item in units[u]]


def _module_fixtures(item: pytest.Item) -> frozenset[str]:
    """The module-scoped fixtures ``item`` uses, directly or through other fixtures."""
    defs = getattr(getattr(item, "_fixtureinfo", None), "name2fixturedefs", {})
    return frozenset(name for name, fds in defs.items() if fds and fds[-1].scope == "module")


def shared_fixtures_last(items: list[pytest.Item]) -> list[pytest.Item]:
    """Each module's tests that use a module-scoped fixture not all of its tests use (one vehicle
    flown by a few tests) moved after the module's other tests, each kind in its order. pytest
    stops a module's fixture only when the module ends: a vehicle shared by two flights in the
    middle of a module flew on, idle, through every test after them (2026-11-28: the link-cut
    tests' ArduCopter and physics through the leg-board test, 30 CPU-s and 17 s of the
    ArduCopter group's wall time)."""
    modules: dict[str, list[pytest.Item]] = {}
    for item in items:
        modules.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    out: list[pytest.Item] = []
    for its in modules.values():
        used = [_module_fixtures(i) for i in its]
        common = frozenset.intersection(*used)
        out += [i for i, u in zip(its, used, strict=True) if u == common]
        out += [i for i, u in zip(its, used, strict=True) if u != common]
    return out


@pytest.hookimpl(tryfirst=True)  # before xdist's worker reads the groups into the test ids
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        group = work_unit(item)
        if group is not None:
            item.add_marker(pytest.mark.xdist_group(group))
    items[:] = work_order(shared_fixtures_last(items), recorded_durations(), recorded_durations(CPU_SECONDS))


_RECORD = os.environ.get("SLOPELANDER_RECORD_DURATIONS")  # benchmarks/suite_time.py sets it
_measured: dict[str, float] = {}
_cpu: dict[str, float] = {}
_spans: dict[str, list] = {}  # nodeid: [worker, first start, last stop] (epoch s)
_cpu_mark = 0.0


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    global _cpu_mark
    if _RECORD:
        from slopelander_sitl.proc_cpu import process_tree_cpu

        _cpu_mark = process_tree_cpu()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """Each phase's CPU (the test's processes included) goes with its report to the controller."""
    global _cpu_mark
    outcome = yield
    if _RECORD:
        from slopelander_sitl.proc_cpu import process_tree_cpu

        now = process_tree_cpu()
        outcome.get_result().user_properties.append(("cpu_s", now - _cpu_mark))
        _cpu_mark = now


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Setup, call and teardown times per test (on the controller: every worker's reports)."""
    if _RECORD:
        nodeid = collection_id(report.nodeid)
        _measured[nodeid] = _measured.get(nodeid, 0.0) + report.duration
        cpu = dict(report.user_properties).get("cpu_s")
        if cpu is not None:
            _cpu[nodeid] = _cpu.get(nodeid, 0.0) + float(cpu)
        node = getattr(report, "node", None)  # xdist's worker on the controller
        worker = getattr(getattr(node, "gateway", None), "id", "main")
        span = _spans.setdefault(nodeid, [worker, report.start, report.stop])
        span[1], span[2] = min(span[1], report.start), max(span[2], report.stop)


def pytest_terminal_summary(terminalreporter, config: pytest.Config) -> None:
    job = getattr(config, "_slopelander_compile", None)
    if job is not None and job.seconds is not None:
        said = f"model compiled or loaded once, beside the first tests: {job.seconds:.1f} s"
        terminalreporter.write_line(said)


def pytest_unconfigure(config: pytest.Config) -> None:
    job = getattr(config, "_slopelander_compile", None)
    if job is not None:
        job.stop()
        shutil.rmtree(job.flag.parent, ignore_errors=True)


def pytest_sessionfinish(session: pytest.Session) -> None:
    if _RECORD and _measured and not hasattr(session.config, "workerinput"):
        Path(_RECORD).write_text(json.dumps(dict(sorted(_measured.items())), indent=0) + "\n")
        cpu_path = Path(_RECORD).with_suffix(".cpu.json")
        cpu_path.write_text(json.dumps(dict(sorted(_cpu.items())), indent=0) + "\n")
        spans_path = Path(_RECORD).with_suffix(".spans.json")
        spans_path.write_text(json.dumps(dict(sorted(_spans.items())), indent=0) + "\n")
