"""An independent truth for the identification proofs: the model's equations integrated by
scipy's solve_ivp (not the analysis' fixed-step integrator), hidden effects written here in
plain Python (not the candidates' files), recorded by a motion-capture model (200 Hz, latency,
marker jitter, dropped frames); optionally a base physics that departs a little from the
model's (:data:`DEPARTURES`). Physics in :mod:`.physics`, measurement in :mod:`.mocap`."""

from slopelander.ident.truth.mocap import MotionCapture, record
from slopelander.ident.truth.physics import (
    DEPARTURES,
    HIDDEN,
    Departure,
    HiddenEffect,
    TruthLanding,
    truth_states,
)

__all__ = [
    "DEPARTURES",
    "HIDDEN",
    "Departure",
    "HiddenEffect",
    "MotionCapture",
    "TruthLanding",
    "record",
    "truth_states",
]
