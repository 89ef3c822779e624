"""Helpers shared by the model tests (imported by name: this folder is on sys.path)."""

from dataclasses import replace

from slopelander.model import Model
from slopelander.model.placement import settle_on_slope, slide_after  # noqa: F401 (re-exported)


def with_dt(model: Model, dt: float) -> Model:
    return replace(model, dt=dt)
