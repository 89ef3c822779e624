""" "compiling the model ... ten seconds or more" is said when numba compiles, not on any slow start."""

from __future__ import annotations

import time

import numba
import pytest

from slopelander.model.usercode import compiling_notice


def test_a_slow_start_without_compiling_says_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    with compiling_notice(after=0.05):
        time.sleep(0.4)  # as loading the cached code on a busy machine
    time.sleep(0.1)
    assert "compiling" not in capsys.readouterr().err


def test_a_real_compile_is_announced_once(capsys: pytest.CaptureFixture[str]) -> None:
    def fresh(x: float) -> float:  # a new function: nothing cached, numba must compile it
        s = 0.0
        for i in range(10):
            s += x * i
        return s

    compiled = numba.njit(cache=False)(fresh)
    with compiling_notice(after=0.0):
        assert compiled(1.0) == 45.0
        numba.njit(cache=False)(lambda y: y + 1)(1)  # a second compile: still one notice
    time.sleep(0.1)
    err = capsys.readouterr().err
    assert err.count("slopelander: compiling the model") == 1, err


def test_a_short_compile_then_a_slow_load_says_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    numba.njit(cache=False)(lambda y: y - 1)(1)  # numba warmed up: the next compile is short
    with compiling_notice(after=2.0):
        numba.njit(cache=False)(lambda y: y * 2)(2)  # a tiny compile, well under 2 s
        time.sleep(2.5)  # then slow work that is not compiling
    assert "compiling" not in capsys.readouterr().err
