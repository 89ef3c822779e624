"""The README's test command runs the whole suite on parallel workers (pytest-xdist, addopts in
pyproject.toml): a module's tests, which may share a vehicle, must stay together on one worker in
order (tests/conftest.py). That every worker collects the same tests in the same order is checked
by xdist itself on every run of that command: a difference is a collection error that fails the
run ("Different tests were collected between gw0 and gw1", xdist/scheduler/loadscope.py); a
test that collected the suite twice more to check it cost about 36 CPU-s of every run."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: runs while the model compiles (tests/compile_once.py): no test here needs it
pytestmark = pytest.mark.model_free


def _env() -> dict[str, str]:
    """The environment of a fresh pytest run: none of this run's worker variables."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "HYPOTHESIS_"))}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), str(REPO)])
    env["SLOPELANDER_COMPILE_ONCE"] = "0"  # toy modules: no model to compile first
    return env


def _toy_project(root: Path) -> None:
    """A project with this repository's pytest settings and test-wide conftest, no tests yet."""
    shutil.copy(REPO / "pyproject.toml", root / "pyproject.toml")
    (root / "tests").mkdir()
    shutil.copy(REPO / "tests" / "conftest.py", root / "tests" / "conftest.py")


SHARED = """
import os, pytest, time

@pytest.fixture(scope="module")
def vehicle(tmp_path_factory):
    with open(os.environ["MADE"], "a") as f:
        f.write(os.environ.get("PYTEST_XDIST_WORKER", "-") + "\\n")
    return object()

@pytest.mark.parametrize("n", range(4))
def test_shared(vehicle, n):
    time.sleep(0.3)
    with open(os.environ["RAN"], "a") as f:
        f.write(f"shared {n} {os.environ['PYTEST_XDIST_WORKER']}\\n")
"""

SPREAD = """
import os, pytest, time

pytestmark = pytest.mark.spread

@pytest.mark.parametrize("n", range(4))
def test_spread(n):
    time.sleep(0.3)
    with open(os.environ["RAN"], "a") as f:
        f.write(f"spread {n} {os.environ['PYTEST_XDIST_WORKER']}\\n")
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: -n auto starts one worker")
def test_the_configured_command_runs_a_module_on_one_worker_in_order(tmp_path: Path) -> None:
    """The README's command (``python3 -m pytest``, nothing more) in a project with this
    repository's pytest settings and test-wide conftest: two or more workers; a module's
    module-scoped fixture made once and its tests in file order on one worker; a ``spread``
    module's tests shared out."""
    _toy_project(tmp_path)
    (tmp_path / "tests" / "test_shared.py").write_text(SHARED)
    (tmp_path / "tests" / "test_other.py").write_text(SHARED.replace("shared", "other"))
    (tmp_path / "tests" / "test_spread_out.py").write_text(SPREAD)
    made, ran = tmp_path / "made", tmp_path / "ran"
    env = {**_env(), "MADE": str(made), "RAN": str(ran)}
    done = subprocess.run(
        [sys.executable, "-m", "pytest"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    out = done.stdout + done.stderr
    assert done.returncode == 0, out[-3000:]
    workers = re.search(r"created: (\d+)/(\d+) workers", out)
    assert workers and int(workers[1]) >= 2, out[-3000:]
    assert "12 passed" in out, out[-3000:]
    assert len(made.read_text().split()) == 2  # one per module that has it, not one per worker
    rows = [line.split() for line in ran.read_text().splitlines()]
    for module in ("shared", "other"):
        mine = [(int(n), w) for m, n, w in rows if m == module]
        assert [n for n, _ in mine] == [0, 1, 2, 3], rows  # file order
        assert len({w for _, w in mine}) == 1, rows  # one worker
    assert len({w for m, _, w in rows if m == "spread"}) >= 2, rows


def test_a_recorded_run_orders_the_next_one_longest_first(tmp_path: Path) -> None:
    """The times a run records (``SLOPELANDER_RECORD_DURATIONS``, as benchmarks/suite_time.py
    sets it) order the next run's work units: the slowest module, last by name, comes first. The
    record is written on the controller, where xdist has appended each test's ``@group``; the
    order is made in the workers before it does, on the ids a run without workers collects (a
    mismatch once counted every test as unknown, and units went by their number of tests)."""
    _toy_project(tmp_path)
    (tmp_path / "tests" / "test_shared.py").write_text(SHARED.replace("sleep(0.3)", "sleep(0.02)"))
    (tmp_path / "tests" / "test_zlong.py").write_text(
        SHARED.replace("shared", "zlong").replace("sleep(0.3)", "sleep(0.2)")
    )
    record = tmp_path / "tests" / "durations.json"
    env = {**_env(), "MADE": str(tmp_path / "made"), "RAN": str(tmp_path / "ran")}

    def pytest(*args: str, **extra: str) -> str:
        done = subprocess.run(
            [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args],
            cwd=tmp_path,
            env={**env, **extra},
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
        return done.stdout

    pytest("-n", "1", SLOPELANDER_RECORD_DURATIONS=str(record))
    assert "tests/test_zlong.py::test_zlong[3]" in json.loads(record.read_text()), record.read_text()
    # where and when each test ran, for the report of the minutes the cores stood idle
    spans = json.loads(record.with_suffix(".spans.json").read_text())
    worker, start, stop = spans["tests/test_zlong.py::test_zlong[3]"]
    assert worker == "gw0" and 0.2 <= stop - start < 60, spans
    assert len(spans) == 8, spans
    order = [ln.split("::")[0] for ln in pytest("-n", "0", "--collect-only", "-q").splitlines() if "::" in ln]
    assert order == ["tests/test_zlong.py"] * 4 + ["tests/test_shared.py"] * 4, order


def test_recorded_ids_lose_only_xdists_group_suffix() -> None:
    from tests.conftest import collection_id

    assert collection_id("tests/a.py::t[1]@tests/a.py") == "tests/a.py::t[1]"
    assert collection_id("tests/a.py::t@arducopter") == "tests/a.py::t"
    assert collection_id("tests/a.py::t[x@y]") == "tests/a.py::t[x@y]"
    assert collection_id("tests/a.py::t[x@y]@tests/a.py") == "tests/a.py::t[x@y]"
    assert collection_id("tests/a.py::t") == "tests/a.py::t"


def test_a_record_written_with_xdists_suffixes_still_orders(tmp_path: Path) -> None:
    from tests.conftest import recorded_durations

    record = tmp_path / "durations.json"
    record.write_text('{"tests/a.py::t[1]@tests/a.py": 3.5, "tests/f.py::t@arducopter": 9}')
    assert recorded_durations(record) == {"tests/a.py::t[1]": 3.5, "tests/f.py::t": 9.0}


SHARED_MIDWAY = """
import pytest

@pytest.fixture(scope="module")
def vehicle():
    yield object()

def test_first(vehicle):
    pass

def test_second(vehicle):
    pass

def test_alone():
    pass
"""


def test_a_vehicle_shared_midway_is_stopped_after_its_last_flight(tmp_path: Path) -> None:
    """A module-scoped fixture used by some of a module's tests ends right after the last of
    them: the tests that do not use it run first. pytest ends a module's fixtures only when the
    module ends, so a vehicle shared by two flights before a third flew on, idle, through it."""
    _toy_project(tmp_path)
    (tmp_path / "tests" / "test_midway.py").write_text(SHARED_MIDWAY)
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "0", "--setup-plan", "-q"],
        cwd=tmp_path,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    steps = [
        ln.split()[-1] if "M vehicle" in ln else ln.split("::")[1].split()[0]
        for ln in done.stdout.splitlines()
        if "M vehicle" in ln or "(fixtures used" in ln  # not the durations' lines
    ]
    assert steps == ["test_alone", "vehicle", "test_first", "test_second", "vehicle"], done.stdout


GROUPS_PLUGIN = """
def pytest_collection_finish(session):
    for item in session.items:
        groups = [m.args[0] if m.args else m.kwargs["name"] for m in item.iter_markers("xdist_group")]
        print("GROUP", item.nodeid, groups[0] if groups else "-")
"""


def test_only_flights_on_arducopter_join_its_work_unit(tmp_path: Path) -> None:
    """The landings on both autopilots: each ArduCopter flight in the one "arducopter" unit (never
    two ArduCopters at once), the flights on the simulated vehicle in their module's unit."""
    (tmp_path / "groups_plugin.py").write_text(GROUPS_PLUGIN)
    env = _env()
    env["PYTHONPATH"] += os.pathsep + str(tmp_path)
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-p",
            "no:cacheprovider",
            "-p",
            "groups_plugin",
            "-n",
            "0",
            "--collect-only",
            "-q",
            "tests/flights",
        ],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    ).stdout
    groups = dict(line.split()[1:3] for line in out.splitlines() if line.startswith("GROUP "))
    ap = {k: v for k, v in groups.items() if "[ardupilot" in k}
    sim = {k: v for k, v in groups.items() if "[sim" in k}
    assert ap and sim, out[-2000:]
    assert set(ap.values()) == {"arducopter"}, ap
    assert set(sim.values()) == {"tests/flights/test_landings_on_both_autopilots.py"}, sim


def test_work_units_are_handed_out_longest_first(tmp_path: Path) -> None:
    """The recorded times order the units, longest first, each unit's tests kept together in
    their order; with no record, units with more tests first (xdist's own rule)."""
    from tests.conftest import recorded_durations, work_order

    class Item:
        def __init__(self, nodeid: str) -> None:
            self.nodeid = nodeid

        def get_closest_marker(self, name: str):
            return None

    ids = ["a.py::t1", "a.py::t2", "b.py::t1", "c.py::t1", "c.py::t2"]
    items = [Item(i) for i in ids]
    record = tmp_path / "durations.json"
    record.write_text('{"a.py::t1": 1, "a.py::t2": 1, "b.py::t1": 30, "c.py::t1": 5, "c.py::t2": 0}')
    ordered = [i.nodeid for i in work_order(items, recorded_durations(record))]
    assert ordered == ["b.py::t1", "c.py::t1", "c.py::t2", "a.py::t1", "a.py::t2"]
    record.write_text("not json")
    assert recorded_durations(record) == {}
    unrecorded = [i.nodeid for i in work_order(items, {})]
    assert unrecorded == ["a.py::t1", "a.py::t2", "c.py::t1", "c.py::t2", "b.py::t1"]


def test_units_that_need_no_model_go_first_while_it_compiles() -> None:
    from tests.conftest import work_order

    class Item:
        def __init__(self, nodeid: str, free: bool) -> None:
            self.nodeid, self.free = nodeid, free

        def get_closest_marker(self, name: str):
            return object() if name == "model_free" and self.free else None

    items = [Item("a.py::t1", False), Item("f.py::t1", True), Item("g.py::t1", True), Item("m.py::t1", True)]
    items.append(Item("m.py::t2", False))  # one test of m needs the model: m waits with the others
    seconds = {"a.py::t1": 60.0, "f.py::t1": 1.0, "g.py::t1": 5.0, "m.py::t1": 1.0, "m.py::t2": 1.0}
    ordered = [i.nodeid for i in work_order(items, seconds)]
    assert ordered == ["g.py::t1", "f.py::t1", "a.py::t1", "m.py::t1", "m.py::t2"]


def test_light_units_are_spread_between_the_heavy_ones() -> None:
    """With each test's CPU recorded, the units whose processes keep fewer than LIGHT_CORES busy
    and the others are merged, each longest first, so that each kind's share of its own total
    stays level along the queue: two workers taking units as they free up then mostly run a light
    one beside a heavy one, not two light ones side by side at the end."""
    from tests.conftest import LIGHT_CORES, work_order

    class Item:
        def __init__(self, nodeid: str, free: bool = False) -> None:
            self.nodeid, self.free = nodeid, free

        def get_closest_marker(self, name: str):
            return object() if name == "model_free" and self.free else None

    wall = {"h1.py::t": 100.0, "h2.py::t": 40.0, "l1.py::t": 60.0, "l2.py::t": 30.0, "l3.py::t": 10.0}
    wall["f.py::t"] = 5.0
    cpu = {"h1.py::t": 130.0, "h2.py::t": 40.0, "l1.py::t": 20.0, "l2.py::t": 10.0, "l3.py::t": 2.0}
    cpu["f.py::t"] = 5.0
    assert cpu["h2.py::t"] / wall["h2.py::t"] >= LIGHT_CORES > cpu["l1.py::t"] / wall["l1.py::t"]
    items = [Item(i) for i in wall if i != "f.py::t"] + [Item("f.py::t", free=True)]
    ordered = [i.nodeid.split(".")[0] for i in work_order(items, wall, cpu)]
    # heavy 0 -> 100/140, light 0 -> 60/100 -> 90/100, heavy -> 140/140, light's last
    assert ordered == ["f", "h1", "l1", "l2", "h2", "l3"]
    # by length alone without a CPU record
    assert [i.nodeid.split(".")[0] for i in work_order(items, wall)] == ["f", "h1", "l1", "h2", "l2", "l3"]
