"""The "compiling" notice appears for a real compile only, not for a slow start or a long batch."""

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


def test_a_slow_start_that_compiles_nothing_is_not_called_compiling(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Only numba's own compile event arms the notice (tests/cli/test_compile_notice.py shows it
    said for a real compile): a start slowed by a busy machine or a cache load is not one."""
    with compiling_notice("the model", after=0.2):
        time.sleep(0.5)
    assert "compiling" not in capsys.readouterr().err
