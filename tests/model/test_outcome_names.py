"""Outcomes read as names wherever a person reads them; codes stay integers for machines."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np

from slopelander.model import (
    OUTCOME_NAMES,
    LandingConditions,
    Outcome,
    outcome_names,
    simulate_batch,
)

README = Path(__file__).resolve().parents[2] / "docs" / "commands.md"  # the Python example moved here


def test_an_outcome_prints_as_its_name_and_converts_to_its_code() -> None:
    assert str(Outcome.END_OF_TRAVEL) == "end_of_travel"
    assert f"{Outcome.FLIP}" == "flip" and f"{Outcome.IDEAL:>6}" == " ideal"
    assert int(Outcome.SLID) == 3 and Outcome(3) is Outcome.SLID
    assert OUTCOME_NAMES == ("ideal", "under_used", "end_of_travel", "slid", "joint_touch", "flip", "damaged")
    assert int(Outcome.DAMAGED) == 6 and not Outcome.DAMAGED.success


def test_batch_results_hold_integer_codes_and_name_them() -> None:
    res = simulate_batch([LandingConditions(), LandingConditions(slope_deg=70, speed=3.0)])
    assert res["outcome"].dtype.kind == "i"
    names = outcome_names(res["outcome"])
    assert names.shape == (2,)
    assert list(names) == [str(Outcome(int(c))) for c in res["outcome"]]
    assert outcome_names(np.array([[0, 5]])).tolist() == [["ideal", "flip"]]


def test_the_readme_python_snippet_prints_outcome_names() -> None:
    text = README.read_text()
    snippet = next(b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "simulate_batch" in b)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(snippet, str(README), "exec"), {})
    first, second = out.getvalue().splitlines()[:2]
    assert first.split()[0] in OUTCOME_NAMES, first
    assert all(w.strip("[]'") in OUTCOME_NAMES for w in second.split()), second
