"""The suite's compile beside its first tests (tests/compile_once.py): the flag it leaves and
what a waiting test reads from it."""

from __future__ import annotations

import time
from pathlib import Path

from tests.compile_once import BackgroundCompile, wait_for_model


def test_a_compile_that_ended_well_lets_the_tests_go(tmp_path: Path) -> None:
    flag = tmp_path / "done"
    job = BackgroundCompile(flag)  # the cache is warm by now: it loads the model
    try:
        assert wait_for_model(flag, timeout_s=300) is None
        assert flag.read_text().startswith("ok ") and job.seconds is not None
        assert not flag.with_suffix(".tmp").exists()
    finally:
        job.stop()
    assert not flag.exists() and not flag.with_suffix(".tmp").exists()


def test_a_failed_compile_is_said_with_its_error(tmp_path: Path) -> None:
    flag = tmp_path / "done"
    flag.write_text("failed 1\nTraceback ...\nTypingError: Cannot unify float64 and int64\n")
    why = wait_for_model(flag, timeout_s=1)
    assert why is not None and why.startswith("the model does not compile: Traceback")
    assert "Cannot unify" in why


def test_a_compile_that_never_ends_is_given_up_on(tmp_path: Path) -> None:
    t0 = time.monotonic()
    why = wait_for_model(tmp_path / "never", timeout_s=0.3)
    assert why == "the model's compile did not end within 0.3 s"
    assert 0.3 <= time.monotonic() - t0 < 5.0


def test_a_flag_whose_folder_went_away_is_not_waited_for(tmp_path: Path) -> None:
    t0 = time.monotonic()
    why = wait_for_model(tmp_path / "gone" / "done", timeout_s=60)
    assert why is not None and why.startswith("the model's compile flag's folder") and "is gone" in why
    assert time.monotonic() - t0 < 5.0
