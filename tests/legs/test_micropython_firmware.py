"""The leg-board firmware on the real MicroPython, over its plant: the clamp and the
protections behave as on CPython (``test_leg_firmware.py``), and a seeded scenario gives the same
numbers on both interpreters, since the plant draws its noise from its own generator."""

from __future__ import annotations

import sys

import pytest

from slopelander_sitl.legboard.runtime import FIRMWARE_DIR, HostBoard
from tests.legs.micropython_runner import needs_micropython, run

#: its tests share one run on both runtimes (both): one worker, file order (tests/conftest.py)
pytestmark = [needs_micropython, pytest.mark.xdist_group("legs/micropython_firmware")]

# the same source runs below on MicroPython (as a string) and here on CPython (exec)
SCENARIO = """
import json
from legfw.host import HostBoard


def clamp(seed, targets):
    b = HostBoard(seed=seed)
    for leg, ma in enumerate(targets):
        b.fw.legs[leg].set_friction(ma)
    held = [None] * 4
    while b.time_s < 25 and None in held:
        b.advance(b.time_s + 0.02)
        for leg in range(4):
            if held[leg] is None and b.fw.legs[leg].state == 3:
                held[leg] = round(b.time_s, 3)
    return {
        "held_at_s": held,
        "torque_nm": [b.plant.legs[i].friction_torque() for i in range(4)],
        "reports": [list(b.fw.legs[i].report()) for i in range(4)],
    }


def fault(kind):
    b = HostBoard()
    b.inject(kind, 2)
    b.fw.legs[2].set_friction(100)
    t0 = b.time_s
    while b.time_s - t0 < 30 and b.fw.legs[2].state != 6:
        b.advance(b.time_s + 0.02)
    return [b.fw.legs[2].fault, round(b.time_s - t0, 3), b.plant.legs[2].volts]


def silence():
    b = HostBoard()
    b.fw.handle(0x01, 0, (3, 100))
    b.fw.handle(0x02, 1, (1, (100, 0, 0, 0)))
    while b.time_s < 30 and b.fw.legs[0].state != 4:
        b.advance(b.time_s + 0.02)
    return [b.fw.legs[0].state, round(b.time_s - b.fw.last_heard_ms / 1000, 3)]


result = {
    "clamp": clamp(3, (60, 78, 103, 119)),
    "faults": {k: fault(k) for k in ("stuck", "overcurrent", "sense", "slip")},
    "silence": silence(),
}
print(json.dumps(result))
"""


@pytest.fixture(scope="module")
def both():
    (on_micropython,) = run(SCENARIO)
    printed = []
    sys.path.insert(0, str(FIRMWARE_DIR))
    scope = {"print": lambda text: printed.append(text)}
    exec(SCENARIO, scope)  # the same scenario on CPython
    import json

    return on_micropython, json.loads(printed[0])


def test_the_clamp_on_micropython_takes_about_ten_seconds_and_reaches_its_target(both):
    mp, _ = both
    assert all(8.0 <= t <= 12.5 for t in mp["clamp"]["held_at_s"][2:])  # 1.7 and 2.3 N·m from loose
    for leg, (want_ma, tau) in enumerate(zip((60, 78, 103, 119), (0.56, 1.1, 1.7, 2.3), strict=True)):
        state, fault, current, target, _angle = mp["clamp"]["reports"][leg]
        assert (state, fault, target) == (3, 0, want_ma) and abs(current - want_ma) <= 2
        assert mp["clamp"]["torque_nm"][leg] == pytest.approx(tau, abs=0.08)


def test_the_protections_on_micropython(both):
    mp, _ = both
    faults = mp["faults"]
    assert [faults[k][0] for k in ("stuck", "overcurrent", "sense", "slip")] == [2, 1, 4, 5]
    assert all(faults[k][1] < 0.5 for k in ("stuck", "overcurrent", "sense"))
    assert all(f[2] == 0.0 for f in faults.values())  # the motor braked
    state, silent_s = mp["silence"]
    assert state == 4 and 10.0 <= silent_s <= 10.1


def test_micropython_and_cpython_give_the_same_numbers(both):
    mp, cp = both
    assert mp["clamp"]["held_at_s"] == cp["clamp"]["held_at_s"]
    assert mp["clamp"]["reports"] == cp["clamp"]["reports"]
    assert mp["clamp"]["torque_nm"] == pytest.approx(cp["clamp"]["torque_nm"], rel=1e-9)
    assert mp["faults"] == cp["faults"] and mp["silence"] == cp["silence"]


def test_the_firmware_fits_the_heap_of_a_pico():
    """The firmware, its plant and a clamp of four legs in the 192 KB a Pico leaves free."""
    (free,) = run(
        "import gc, json\nfrom legfw.host import HostBoard\nb = HostBoard()\n"
        "[b.fw.legs[i].set_friction(120) for i in range(4)]\n"
        "b.advance(b.time_s + 8)\nb.advance(b.time_s + 5)\n"
        "gc.collect()\nprint(json.dumps([gc.mem_alloc(), gc.mem_free(), [l.state for l in b.fw.legs]]))\n"
    )
    alloc, _free, states = free
    assert states == [3, 3, 3, 3] and alloc < 120_000


assert HostBoard  # the in-process firmware the CPython half runs is slopelander_sitl.legboard's


def test_the_reference_boards_code_compiles_on_micropython_and_its_config_loads():
    """What runs on the Pico itself (its HAL, the encoder's PIO program, main.py) needs the
    Pico's modules to run; here MicroPython's own compiler checks it, and the shipped
    config.json is read by the firmware's loader."""
    files = ["legfw/rp2040.py", "legfw/pio.py", "main.py"]
    (out,) = run(
        "import json\n"
        f"base = {str(FIRMWARE_DIR)!r}\n"
        f"for f in {files!r}:\n"
        "    compile(open(base + '/' + f).read(), f, 'exec')\n"
        "from legfw.config import Config\n"
        "cfg = Config.from_json(base + '/config.json')\n"
        "print(json.dumps([cfg.angle_stop, cfg.max_target_ma, list(cfg.angle_zero_cdeg), cfg.tick_ms]))\n"
    )
    assert out == [False, 175, [0, 0, 0, 0], 4]
