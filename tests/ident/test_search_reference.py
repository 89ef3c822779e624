"""The default search gives, bit for bit, what the search gave before its optimizer became
pluggable: the reference numbers in ``search_reference.json`` were written by the code of
7d883ab (``_search`` and ``diagnose`` as single long functions) on this file's cases, and
rewritten on 2026-12-07 when the polish gained its step over the kinks (``_Polish.over_kinks``)
and the intervals their wide central differences (``INTERVAL_STEP``), which move them on purpose.

A change to the model's physics moves these numbers too: then rewrite the reference with the
code before the search change and after the physics change,
``PYTHONPATH=src python3 tests/ident/test_search_reference.py --write``, and say so in the commit.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from slopelander.ident.diagnose import diagnose
from slopelander.ident.fit import Identifier
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize
from slopelander.model import Model

REFERENCE = Path(__file__).with_name("search_reference.json")


def _drops(model: Model, n: int, seed: int, duration: float):
    return synthesize(model, paper_drops(n, seed=seed), NoiseModel(), seed=seed, duration=duration)


def _fit_record(r) -> dict:
    return {
        "values": r.values,
        "u": [float(x) for x in r.u],
        "cost": r.cost,
        "train_nrmse": r.train_nrmse,
        "validation_nrmse": r.validation_nrmse,
        "ci95": r.ci95,
        "warnings": r.warnings,
        "nfev": r.nfev,
        "start_values": r.start_values,
        "start_cost": r.start_cost,
        "start_nrmse": r.start_nrmse,
    }


def case_two_parameters() -> dict:
    """CMA-ES from the model with a restart, an extra start and a point tried first; the polish."""
    model = Model.default()
    truth = model.with_params(ground_stiffness=3.0e4, friction_kinetic=0.65)
    drops = _drops(truth, 4, 4, 0.4)
    ident = Identifier(
        model,
        ["ground_stiffness", "friction_kinetic"],
        cma_evals=64,
        ls_evals=5,
        seed=5,
        restarts=1,
        starts=[{"friction_kinetic": 0.7}],
        also=[{"ground_stiffness": 2.5e4}],
        workers=1,
    )
    return _fit_record(ident.fit(drops[:3], drops[3:]).result_)


def case_one_parameter() -> dict:
    """One parameter: the line scan in place of CMA-ES, then the polish."""
    model = Model.default()
    drops = _drops(model.with_params(friction_kinetic=0.7), 3, 2, 0.3)
    return _fit_record(
        Identifier(model, ["friction_kinetic"], cma_evals=12, ls_evals=4, workers=1).fit(drops).result_
    )


def case_diagnose() -> dict:
    """A small diagnosis: the base and control fits, every built-in candidate, the verdict."""
    model = Model.default()
    truth = model.without("downhill_torque_growth", "downhill_friction_growth")
    drops = _drops(truth, 6, 1, 0.3)
    d = diagnose(
        truth.without("leg_flex"),
        drops,
        names=["friction_kinetic", "ground_stiffness"],
        seed=1,
        cma_evals=24,
        refit_evals=16,
        ls_evals=2,
        workers=1,
        stall=None,  # every search to its budget, as the reference's code did
    )
    out = d.to_dict()
    out["base_fits"] = [_fit_record(f) for f in d.base]
    out["candidate_fits"] = {r.candidate.name: [_fit_record(f) for f in r.fits] for r in d.results}
    out["final"] = None if d.final is None else _fit_record(d.final)
    return out


CASES = {
    "two_parameters": case_two_parameters,
    "one_parameter": case_one_parameter,
    "diagnose": case_diagnose,
}


def _plain(x):
    """JSON's view of a record: tuples as lists, NaN and inf kept (compared as equal to themselves)."""
    return json.loads(json.dumps(x, default=lambda v: v.item() if isinstance(v, np.generic) else str(v)))


def assert_same(a, b, where: str = "") -> None:
    if isinstance(a, dict):
        assert set(a) == set(b), f"{where}: keys {sorted(a)} != {sorted(b)}"
        for k in a:
            assert_same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), f"{where}: {len(a)} items != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        assert math.isnan(b), f"{where}: nan != {b!r}"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_default_search_is_the_reference_bit_for_bit(case):
    want = json.loads(REFERENCE.read_text())[case]
    assert_same(_plain(CASES[case]()), want, case)


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: PYTHONPATH=src python3 tests/ident/test_search_reference.py --write")
    REFERENCE.write_text(json.dumps({k: _plain(f()) for k, f in CASES.items()}, indent=1) + "\n")
    print(f"written: {REFERENCE}")
