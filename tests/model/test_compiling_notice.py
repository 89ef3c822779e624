"""The "compiling" notice appears for a slow first call only, not for every long batch."""

from __future__ import annotations

import time

import pytest

from slopelander.model import LandingConditions, Model, simulate_batch
from slopelander.model.usercode import compiling_notice


def test_a_long_call_to_compiled_code_is_not_called_compiling(capsys: pytest.CaptureFixture[str]) -> None:
    model = Model.default()
    simulate_batch([LandingConditions()], model)
    km, _ = model.kernel()
    capsys.readouterr()
    with compiling_notice(dispatcher=km.run_batch, after=0.2):
        time.sleep(0.5)
    assert "compiling" not in capsys.readouterr().err


def test_a_slow_first_call_says_it_is_compiling(capsys: pytest.CaptureFixture[str]) -> None:
    with compiling_notice("the model", after=0.2):
        time.sleep(0.5)
    assert "slopelander: compiling the model" in capsys.readouterr().err
