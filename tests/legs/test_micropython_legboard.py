"""The companion's real driver, over a real pseudo-terminal, against the leg-board firmware
running on the real MicroPython (``python -m slopelander_sitl.legboard --runtime micropython``)."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from slopelander.legs import BoardDisconnected, LegBoard, LegFault, ProtocolError
from slopelander.legs.messages import FaultCode, LegState
from tests.legs.conftest import ROOT
from tests.legs.micropython_runner import needs_micropython

MP = ("--runtime", "micropython")


@needs_micropython
def test_the_driver_sets_and_loosens_legs_on_the_micropython_firmware(sim_board):
    board = sim_board(*MP)
    with board.ctl() as ctl:
        assert ctl.state()["runtime"] == "micropython"
    with LegBoard.open(str(board.link), timeout=3.0) as drv:
        info = drv.info
        assert (info.version, info.legs, info.firmware, info.simulated) == (3, 4, "1.0", True)
        assert info.board_id == "53494d424f415244"
        results = drv.set_torques(uphill=1.7, downhill=2.3, timeout=board.wall(25))
        for leg, r in results.items():
            assert r.converged and abs(r.achieved - (1.7 if leg < 2 else 2.3)) <= 0.1
        assert 8.0 <= results[3].board_seconds <= 12.5  # the paper's ≈10 s, in board time
        with board.ctl() as ctl:
            torques = ctl.friction_torques()
            ctl.set_joint_angles([20.0, 25.0, 15.0, 30.0])  # the landing compresses the legs
        assert torques == pytest.approx([1.7, 1.7, 2.3, 2.3], abs=0.15)
        drv.loosen_all(timeout=board.wall(25))
        assert [s.state for s in drv.query().legs] == [LegState.LOOSE] * 4
        assert [s.angle_deg for s in drv.query().legs] == pytest.approx([37.5] * 4, abs=0.2)


@needs_micropython
def test_faults_on_the_micropython_firmware_reach_the_driver(sim_board):
    board = sim_board(*MP, "--fault", "stuck:1")
    with LegBoard.open(str(board.link), timeout=3.0) as drv:
        with pytest.raises(LegFault) as err:
            drv.set_torques(uphill=1.1, timeout=board.wall(20))
        assert err.value.leg == 1 and err.value.code == FaultCode.STUCK
        with board.ctl() as ctl:
            ctl.inject("corrupt", rate=0.3)
        drv.silence_timeout = 0.5
        with pytest.raises(ProtocolError, match="rejected"):
            for _ in range(400):
                drv.poll()
                time.sleep(0.005)
    board2 = sim_board(*MP)
    with LegBoard.open(str(board2.link), timeout=3.0) as drv, board2.ctl() as ctl:
        drv.start_presets(uphill_nm=1.7, timeout=board2.wall(20))
        ctl.inject("unplug")
        with pytest.raises(BoardDisconnected):
            for _ in range(200):
                drv.poll()
                time.sleep(0.01)
        assert not board2.link.exists()


def test_asking_for_micropython_without_one_is_a_clear_error(tmp_path):
    env = dict(os.environ)
    env.pop("SLOPELANDER_MICROPYTHON", None)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), str(ROOT)])
    done = subprocess.run(
        [sys.executable, "-m", "slopelander_sitl.legboard", "--link", str(tmp_path / "legs"), *MP],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "--runtime micropython needs SLOPELANDER_MICROPYTHON set to a MicroPython binary" in done.stderr
    env["SLOPELANDER_MICROPYTHON"] = str(tmp_path / "no-such-micropython")
    done = subprocess.run(
        [sys.executable, "-m", "slopelander_sitl.legboard", "--link", str(tmp_path / "legs")],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert done.returncode == 2 and "is not an executable file" in done.stderr
