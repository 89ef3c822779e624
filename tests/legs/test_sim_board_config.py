"""The simulated board's firmware settings from its command line (``--config``, as a real board's
config.json): taken as given, refused with the setting named when wrong."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from slopelander.legs.calibration import load_calibration
from slopelander.legs.driver import LegBoard
from slopelander.legs.messages import LegState


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ('{"silence_ms": "x"}', "setting silence_ms must be int, not 'x'"),
        ('{"nope": 1}', "unknown setting 'nope'"),
        ("[1, 2]", "expected a JSON object of firmware settings"),
        ("{", "not JSON"),
    ],
)
def test_a_wrong_setting_is_refused_by_name(tmp_path: Path, text: str, said: str) -> None:
    (tmp_path / "config.json").write_text(text)
    cmd = [sys.executable, "-m", "slopelander_sitl.legboard", "--config", str(tmp_path / "config.json")]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and said in done.stderr, done.stderr
    assert "Traceback" not in done.stderr


def test_the_silence_setting_is_the_boards(sim_board, tmp_path: Path) -> None:
    """A 5 s companion silence at 20x is 0.25 s of wall time: 0.6 s without a word from the driver
    and the holding legs have switched their motors off (STOPPED), as the firmware's rule says.
    The default (10 s, 0.5 s of wall time at 20x) is what a loaded machine's pause had reached."""
    (tmp_path / "config.json").write_text(json.dumps({"silence_ms": 5000}))
    board = sim_board("--config", str(tmp_path / "config.json"))  # the last --config is the one used
    with LegBoard.open(str(board.link), calibration=load_calibration()) as legs:
        op = legs.start_presets(1.1, 1.1, timeout=board.wall(10.0))
        end = time.monotonic() + board.wall(10.0)
        while not op.done and time.monotonic() < end:
            legs.poll()
            time.sleep(0.005)
        assert op.done and op.exception() is None
        assert {s.state for s in legs.status.legs} == {LegState.HOLDING}
        time.sleep(0.6)  # no poll: no KEEPALIVE goes out
        t_read = time.monotonic()
        while time.monotonic() - t_read < 0.2:
            legs.poll()
        assert {s.state for s in legs.status.legs} == {LegState.STOPPED}
