"""The integrator reproduces the reference landings recorded before its seams were reworked
(tests/model/kernel_reference.py: eleven landings over slopes, speeds, presets and built-in
variants, the docs' user effects on every seam, the simulated vehicle's stepper with and
without a user force, a batch of outcomes).

Tolerance: 1e-12 relative plus 1e-12 absolute on every state entry (round-off; the refactor
kept every operation and its order, so the arrays are expected to agree bit for bit). The state
vector has since grown by the user effects' memory (``layout.S_MEM`` on): no effect recorded here
declares any, so those entries stay zero."""

import kernel_reference as ref
import numpy as np
import pytest

from slopelander.model import layout

#: its tests share recorded and current landings (now, recorded): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("model/kernel_reference")


def _recorded_part(now: np.ndarray, recorded: np.ndarray) -> np.ndarray:
    """``now`` cut to the state entries the references recorded; the memory after them is zero."""
    if now.ndim == 2 and recorded.ndim == 2 and now.shape[1] == layout.N_STATE != recorded.shape[1]:
        assert recorded.shape[1] == layout.S_MEM
        assert not now[:, layout.S_MEM :].any()
        return now[:, : layout.S_MEM]
    return now


RTOL = 1e-12
ATOL = 1e-12


@pytest.fixture(scope="module")
def recorded():
    with np.load(ref.DATA) as data:
        return dict(data)


@pytest.fixture(scope="module")
def now():
    return ref.run_all()


def test_every_reference_is_run(recorded, now):
    assert sorted(now) == sorted(recorded)


@pytest.mark.parametrize("name", sorted(ref.landing_cases()))
def test_landing_matches_reference(name, recorded, now):
    key = f"landing/{name}"
    got = _recorded_part(now[key], recorded[key])
    assert got.shape == recorded[key].shape
    np.testing.assert_allclose(got, recorded[key], rtol=RTOL, atol=ATOL)


@pytest.mark.parametrize(
    "key", ["stepper/default", "stepper/user", "energy/default", "energy/user", "batch/default"]
)
def test_stepper_and_batch_match_reference(key, recorded, now):
    got = _recorded_part(now[key], recorded[key])
    np.testing.assert_allclose(got, recorded[key], rtol=RTOL, atol=ATOL, equal_nan=True)
