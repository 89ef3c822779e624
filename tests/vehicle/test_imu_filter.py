"""The simulated IMU's low-pass is ArduPilot's: a two-pole Butterworth at INS_ACCEL_FILTER
(AP_InertialSensor's ``LowPassFilter2pVector3f``), the same response as scipy's design."""

import numpy as np
import pytest
from scipy.signal import butter, lfilter, lfilter_zi

from slopelander_sitl.vehicle.sensors import LowPass2p

FS, FC = 1200.0, 20.0  # the physics rate, INS_ACCEL_FILTER


def test_the_filter_is_the_two_pole_butterworth_started_at_its_first_sample() -> None:
    rng = np.random.default_rng(4)
    x = np.r_[np.full(20, 9.81), 9.81 + 30.0 * np.exp(-np.arange(200) / 6.0) + rng.normal(0, 0.5, 200)]
    f = LowPass2p()
    ours = np.array([f.apply(np.array([v]), 1.0 / FS, FC)[0] for v in x])
    b, a = butter(2, FC / (FS / 2.0))
    ref, _ = lfilter(b, a, x, zi=lfilter_zi(b, a) * x[0])
    np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-9)


def test_a_short_spike_is_held_lower_than_by_a_first_order_filter() -> None:
    """What changed the landings' impact reading: a 5 ms contact pulse of 5 g from free fall."""
    pulse = np.r_[np.zeros(5), np.full(6, 49.0), np.zeros(60)]
    f = LowPass2p()
    two = max(f.apply(np.array([v]), 1.0 / FS, FC)[0] for v in pulse)
    alpha = (1.0 / FS) / (1.0 / FS + 1.0 / (2 * np.pi * FC))
    y, one = 0.0, 0.0
    for v in pulse:
        y += alpha * (v - y)
        one = max(one, y)
    assert two < 0.75 * one


@pytest.mark.parametrize("cutoff", [0.0, 600.0])
def test_no_cutoff_or_one_at_nyquist_passes_the_sample_through(cutoff: float) -> None:
    f = LowPass2p()
    for v in (1.0, 5.0, -3.0):
        assert f.apply(np.array([v]), 1.0 / FS, cutoff)[0] == v
