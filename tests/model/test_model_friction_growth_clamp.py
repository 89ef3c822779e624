"""Eq. 4 only ever raises the downhill foot's friction: a downhill joint moving uphill fast
must not leave its sliding foot with less than mu_k (or with no friction at all)."""

import numpy as np

from slopelander.model import kernel as k
from slopelander.model.stepper import Stepper


def test_a_sliding_downhill_foot_never_feels_less_than_mu_k() -> None:
    s = Stepper(slope_deg=20.0)
    s.set_friction(0.5, 0.5)
    s.place(height=0.02, vx=-3.0, vz=-1.0, pitch_deg=-15.0)
    mu_k = s.model.params["friction_kinetic"]
    foot = s.downhill  # the feet are the first two contact points
    ratios = []
    for _ in range(300):
        s.step(0.001, 0.0, 0.0)
        n = s.st[k.S_NF + foot]
        if s.st[k.S_CM + foot] in (2.0, 3.0) and n > 1.0:
            ratios.append(abs(s.st[k.S_FT + foot]) / n)
    assert len(ratios) > 20, "the downhill foot should slide in this landing"
    assert np.min(ratios) >= mu_k * (1 - 1e-6)
